// Pre-classified grid tracers (see tracers.h).
#include "render/tracers.h"

namespace fathom {

template Tracer grid_tracer<float, float>(const Volume&, const Volume&, const Renderer::Impl&);
template Tracer grid_tracer<float, double>(const Volume&, const Volume&, const Renderer::Impl&);
template Tracer grid_tracer<double, float>(const Volume&, const Volume&, const Renderer::Impl&);
template Tracer grid_tracer<double, double>(const Volume&, const Volume&, const Renderer::Impl&);

}  // namespace fathom
