// `riemann`: Max's Riemann sum, eq. (9). Each segment is sampled at one point
// (its camera-side end or its midpoint); t_i = exp(−σ_a(x_i)δ), C_i = g(x_i)δ.
#pragma once

#include <cmath>

#include "integrate/accumulator.h"
#include "integrate/ray_span.h"

namespace fathom {

template <Model M, class Medium>
RayResult integrate_riemann(const Medium& medium, const RaySpan& span, const RenderSettings& s, double h,
                            const Rgb& bg) {
    const std::int64_t n = segment_count(span.length(), h);
    const double delta = span.length() / static_cast<double>(n);
    const double offset = s.sample_point == SamplePoint::mid ? 0.5 : 0.0;
    return composite(n, s.order, s.termination, bg, [&](std::int64_t i) {
        const double t = span.t_near + (static_cast<double>(i - 1) + offset) * delta;  // eq. (8)
        MediumSample m = medium.at(span.at(t));
        apply_model<M>(m.sigma, m.source);
        Segment seg{std::exp(-m.sigma * delta), {}};
        for (int c = 0; c < 3; ++c) seg.radiance[c] = m.source[c] * delta;
        return seg;
    });
}

}  // namespace fathom
