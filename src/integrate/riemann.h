// `riemann`: Max's Riemann sum, eq. (9). Each segment is sampled at one point
// (its camera-side end or its midpoint); t_i = exp(−σ_a(x_i)δ), C_i = g(x_i)δ.
#pragma once

#include "integrate/point_rules.h"
#include "integrate/point_sampled.h"

namespace fathom {

template <Model M, class Medium>
RayResult integrate_riemann(const Medium& medium, const RaySpan& span, const RenderSettings& s, double h,
                            const Rgb& bg, const Accel& acc) {
    return integrate_point_sampled<M>(medium, span, s, h, bg, acc, simd::PointRule::riemann, riemann_segment);
}

}  // namespace fathom
