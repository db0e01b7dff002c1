// Scalar-volume tracers for float and double samples (see tracers.h).
#include <cstdint>

#include "render/tracers.h"

namespace fathom {

template Tracer scalar_tracer<float>(const Volume&, const Renderer::Impl&, bool);
template Tracer scalar_tracer<double>(const Volume&, const Renderer::Impl&, bool);

}  // namespace fathom
