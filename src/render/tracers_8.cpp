// Scalar-volume tracers for std::uint8_t and std::int8_t samples (see tracers.h).
#include <cstdint>

#include "render/tracers.h"

namespace fathom {

template Tracer scalar_tracer<std::uint8_t>(const Volume&, const Renderer::Impl&, bool);
template Tracer scalar_tracer<std::int8_t>(const Volume&, const Renderer::Impl&, bool);

}  // namespace fathom
