// The walk shared by the point-sampled quadratures (riemann, alpha): the
// uniform division of eq. (8), one medium sample per segment at its
// camera-side end or midpoint, the model applied, and a rule that turns the
// sample into the segment's (transmittance, radiance).
#pragma once

#include "integrate/accumulator.h"
#include "integrate/ray_span.h"
#include "render/empty_space.h"

namespace fathom {

template <Model M, class Medium, class Rule>
RayResult integrate_point_sampled(const Medium& medium, const RaySpan& span, const RenderSettings& s,
                                  double h, const Rgb& bg, const EmptySpace* es, Rule&& rule) {
    const std::int64_t n = segment_count(span.length(), h);
    const double delta = span.length() / static_cast<double>(n);
    const double offset =
        span.sample_offset >= 0.0 ? span.sample_offset : (s.sample_point == SamplePoint::mid ? 0.5 : 0.0);
    const SampleGrid grid{&span, delta, offset, 1};  // eq. (8): segment i sampled at t_{i−1} + offset·δ
    auto segment = [&](std::int64_t i) {
        MediumSample m = medium.at(grid.at(i));
        apply_model<M>(m.sigma, m.source);
        return rule(m, delta);
    };
    if (es == nullptr) return composite(n, s.order, s.termination, bg, segment);
    // Samples in an empty macrocell give (1, 0): skip each run of them;
    // evaluate each run in a non-empty one without further lookups.
    const RunFinder runs(*es, grid);
    return composite(n, s.order, s.termination, bg, segment, [&](std::int64_t i, int dir) {
        const auto run = runs.run(i, dir, dir > 0 ? n : 1);
        const std::int64_t count = dir * (run.last - i) + 1;
        return run.empty ? count : -count;
    });
}

}  // namespace fathom
