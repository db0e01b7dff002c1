// Scalar-volume tracers for std::uint16_t and std::int16_t samples (see tracers.h).
#include <cstdint>

#include "render/tracers.h"

namespace fathom {

template Tracer scalar_tracer<std::uint16_t>(const Volume&, const Renderer::Impl&, bool);
template Tracer scalar_tracer<std::int16_t>(const Volume&, const Renderer::Impl&, bool);

}  // namespace fathom
