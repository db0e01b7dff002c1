// The walk shared by the point-sampled quadratures (riemann, alpha): the
// uniform division of eq. (8), one medium sample per segment at its
// camera-side end or midpoint, the model applied, and a rule that turns the
// sample into the segment's (transmittance, radiance).
#pragma once

#include "integrate/accumulator.h"
#include "integrate/ray_span.h"

namespace fathom {

template <Model M, class Medium, class Rule>
RayResult integrate_point_sampled(const Medium& medium, const RaySpan& span, const RenderSettings& s,
                                  double h, const Rgb& bg, Rule&& rule) {
    const std::int64_t n = segment_count(span.length(), h);
    const double delta = span.length() / static_cast<double>(n);
    const double offset =
        span.sample_offset >= 0.0 ? span.sample_offset : (s.sample_point == SamplePoint::mid ? 0.5 : 0.0);
    return composite(n, s.order, s.termination, bg, [&](std::int64_t i) {
        const double t = span.t_near + (static_cast<double>(i - 1) + offset) * delta;  // eq. (8)
        MediumSample m = medium.at(span.at(t));
        apply_model<M>(m.sigma, m.source);
        return rule(m, delta);
    });
}

}  // namespace fathom
