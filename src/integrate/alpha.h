// `alpha`: the NeRF quadrature, eq. (12). σ_a and g are held constant over
// each segment at its sample point; the segment's radiance is the exact
// integral of that constant medium: g·(1 − e^{−σδ})/σ (g·δ where σ = 0).
#pragma once

#include <cmath>

#include "integrate/accumulator.h"
#include "integrate/ray_span.h"

namespace fathom {

template <Model M, class Medium>
RayResult integrate_alpha(const Medium& medium, const RaySpan& span, const RenderSettings& s, double h,
                          const Rgb& bg) {
    const std::int64_t n = segment_count(span.length(), h);
    const double delta = span.length() / static_cast<double>(n);
    const double offset = s.sample_point == SamplePoint::mid ? 0.5 : 0.0;
    return composite(n, s.order, s.termination, bg, [&](std::int64_t i) {
        const double t = span.t_near + (static_cast<double>(i - 1) + offset) * delta;  // eq. (8)
        MediumSample m = medium.at(span.at(t));
        apply_model<M>(m.sigma, m.source);
        const double alpha = -std::expm1(-m.sigma * delta);             // α_i = 1 − e^{−σδ}
        const double weight = m.sigma > 0.0 ? alpha / m.sigma : delta;  // (1 − e^{−σδ})/σ
        Segment seg{std::exp(-m.sigma * delta), {}};
        for (int c = 0; c < 3; ++c) seg.radiance[c] = m.source[c] * weight;
        return seg;
    });
}

}  // namespace fathom
