// `riemann`: Max's Riemann sum, eq. (9). Each segment is sampled at one point
// (its camera-side end or its midpoint); t_i = exp(−σ_a(x_i)δ), C_i = g(x_i)δ.
#pragma once

#include <cmath>

#include "integrate/point_sampled.h"

namespace fathom {

template <Model M, class Medium>
RayResult integrate_riemann(const Medium& medium, const RaySpan& span, const RenderSettings& s, double h,
                            const Rgb& bg, const Accel& acc) {
    return integrate_point_sampled<M>(medium, span, s, h, bg, acc, [](const MediumSample& m, double delta) {
        Segment seg{m.sigma == 0.0 ? 1.0 : std::exp(-m.sigma * delta), {}};  // (e^{−0} = 1: the same bits)
        for (int c = 0; c < 3; ++c) seg.radiance[c] = m.source[c] * delta;
        return seg;
    });
}

}  // namespace fathom
