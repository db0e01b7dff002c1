// `alpha`: the NeRF quadrature, eq. (12). σ_a and g are held constant over
// each segment at its sample point; the segment's radiance is the exact
// integral of that constant medium: g·(1 − e^{−σδ})/σ (g·δ where σ = 0).
#pragma once

#include "integrate/point_rules.h"
#include "integrate/point_sampled.h"

namespace fathom {

template <Model M, class Medium>
RayResult integrate_alpha(const Medium& medium, const RaySpan& span, const RenderSettings& s, double h,
                          const Rgb& bg, const Accel& acc) {
    return integrate_point_sampled<M>(medium, span, s, h, bg, acc, simd::PointRule::alpha, alpha_segment);
}

}  // namespace fathom
