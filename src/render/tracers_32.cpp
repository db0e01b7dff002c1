// Scalar-volume tracers for std::uint32_t and std::int32_t samples (see tracers.h).
#include <cstdint>

#include "render/tracers.h"

namespace fathom {

template Tracer scalar_tracer<std::uint32_t>(const Volume&, const Renderer::Impl&, bool);
template Tracer scalar_tracer<std::int32_t>(const Volume&, const Renderer::Impl&, bool);

}  // namespace fathom
