// The walk shared by the point-sampled quadratures (riemann, alpha): the
// uniform division of eq. (8), one medium sample per segment at its
// camera-side end or midpoint, the model applied, and a rule that turns the
// sample into the segment's (transmittance, radiance).
#pragma once

#include <algorithm>
#include <optional>

#include "integrate/accumulator.h"
#include "integrate/ray_span.h"
#include "integrate/simd_classify.h"
#include "render/empty_space.h"

namespace fathom {

/// What speeds a ray up without changing its result: empty-space skipping
/// and SIMD classification of point samples (nullptr: off).
struct Accel {
    const EmptySpace* es = nullptr;
    const simd::BatchSource* simd = nullptr;
};

/// Where a segment's point sample lies in it, as a fraction of δ: a span's
/// jitter (RaySpan::sample_offset) where it is ≥ 0, else the sample_point
/// setting's camera-side end (0) or midpoint (½).
inline double point_offset(SamplePoint p, double jitter = -1.0) {
    return jitter >= 0.0 ? jitter : (p == SamplePoint::mid ? 0.5 : 0.0);
}

/// `rule` turns a sample (after the model) into its segment; `kind` names
/// it, so that a SIMD classifier applying the same rule (BatchSource::rule)
/// hands the segments over directly.
template <Model M, class Medium, class Rule>
RayResult integrate_point_sampled(const Medium& medium, const RaySpan& span, const RenderSettings& s,
                                  double h, const Rgb& bg, const Accel& acc, simd::PointRule kind,
                                  Rule&& rule) {
    const std::int64_t n = segment_count(span.length(), h);
    const double delta = span.length() / static_cast<double>(n);
    const double offset = point_offset(s.sample_point, span.sample_offset);
    const SampleGrid grid{&span, delta, offset, 1};  // eq. (8): segment i sampled at t_{i−1} + offset·δ
    // SIMD: samples classified kBatch at a time, in the direction of travel.
    simd::RayGrid rg{span.p0, span.dp, span.t_near, delta, offset, 1};
    if constexpr (Medium::kShaded) rg.view = medium.view;
    simd::BatchOut batch;
    simd::Window win;
    // The far end of the run being evaluated (set by the skipping walk):
    // batches stop there, since what follows may be skipped.
    std::int64_t run_end = s.order == Order::front_to_back ? n : 1;
    auto load_window = [&](std::int64_t i) {  // the batch from i in the direction of travel
        win.start_at(i, s.order == Order::front_to_back, run_end);
        simd::classify_batch(*acc.simd, rg, win.b0, win.count(), batch);
    };
    auto sample = [&](std::int64_t i) -> MediumSample {
        if constexpr (Medium::kHasScalar) {
            if (acc.simd != nullptr) {
                if (!win.holds(i)) load_window(i);
                const auto l = static_cast<std::size_t>(i - win.b0);
                MediumSample m{batch.sigma[l], {batch.color[0][l], batch.color[1][l], batch.color[2][l]}};
                if (!medium.tf->associated())  // as ScalarMedium::classify
                    for (double& c : m.source) c *= m.sigma;
                if constexpr (Medium::kShaded) medium.shade(grid.at(i), m);
                return m;
            }
        }
        return medium.at(grid.at(i));  // shaded media shade here
    };
    // Scalar media: the classifier applies the rule as well (shaded ones
    // where it shades them).
    const bool batch_rule = Medium::kHasScalar && acc.simd != nullptr && acc.simd->rule == kind &&
                            acc.simd->model == M && (!Medium::kShaded || acc.simd->shade != nullptr);
    auto segment = [&](std::int64_t i) -> Segment {
        if (batch_rule) {
            if (!win.holds(i)) load_window(i);
            const auto l = static_cast<std::size_t>(i - win.b0);
            return {batch.t[l], {batch.radiance[0][l], batch.radiance[1][l], batch.radiance[2][l]}};
        }
        MediumSample m = sample(i);
        apply_model<M>(m.sigma, m.source);
        return rule(m, delta);
    };
    DepthTrack depth{span.t_near, delta};
    DepthTrack* track = s.depth_outputs ? &depth : nullptr;
    const EmptySpace* es = acc.es;
    if constexpr (Medium::kHasScalar) {
        if (acc.simd != nullptr) {
            // With SIMD, samples are classified a batch at a time, and those
            // whose scalar lies below the medium's zero range (BatchOut::zero)
            // give (1, 0): skipped. With skipping, only the runs in non-empty
            // macrocells are classified, kLeastRun samples at least (a run's
            // samples in an empty one give (1, 0) too); without, the whole
            // ray is one run. Shading keeps a zero sample zero (σ' = σ·f,
            // g' = (g·D + σ·S)·f with finite factors), so a shaded medium
            // shades only the others.
            const std::optional<RunFinder> runs =
                es != nullptr ? std::optional<RunFinder>(std::in_place, *es, grid) : std::nullopt;
            bool in_run = es == nullptr;  // i lies in the evaluated run ending at run_end
            return composite(
                n, s.order, s.termination, bg, segment,
                [&](std::int64_t i, int dir) -> std::int64_t {
                    if (!in_run || dir * (run_end - i) < 0) {
                        const auto run = runs->run(i, dir, dir > 0 ? n : 1);
                        if (run.empty) return dir * (run.last - i) + 1;
                        run_end = simd::least_run_end(i, dir, run.last, dir > 0 ? n : 1);
                        in_run = true;
                    }
                    if (!win.holds(i)) load_window(i);
                    return simd::split_zero(
                        batch.zero, i - win.b0, dir,
                        dir > 0 ? std::min(win.b1, run_end) - i + 1 : i - std::max(win.b0, run_end) + 1);
                },
                track);
        }
    }
    if (es == nullptr) return composite(n, s.order, s.termination, bg, segment, NoSkip{}, track);
    // Samples in an empty macrocell give (1, 0): skip each run of them;
    // evaluate each run in a non-empty one without further lookups.
    const RunFinder runs(*es, grid);
    return composite(
        n, s.order, s.termination, bg, segment,
        [&](std::int64_t i, int dir) {
            const auto run = runs.run(i, dir, dir > 0 ? n : 1);
            const std::int64_t count = dir * (run.last - i) + 1;
            run_end = run.last;
            return run.empty ? count : -count;
        },
        track);
}

}  // namespace fathom
