// The projection models over the scalar at the n + 1 segment ends of
// eq. (8): mip (eq. (23), the largest), minip (the smallest) and average
// (the trapezoidal mean along the ray, exact where v is linear along it);
// I = c(v) (q(v) for an emission transfer function), α = 1 where the ray
// meets the box.
//
// The ends are interpolated kBatch at a time (simd::interpolate_batch,
// GridSampler's bits) and folded in order, so the result is the scalar
// loop's bit for bit. With macrocell ranges, mip and minip skip a batch
// whose ends all lie in macrocells that cannot beat the value so far:
// samples no larger (mip) or no smaller (minip) leave it unchanged, and a
// ray whose first batch reaches the lattice's extreme takes no bounds.
// With coarse ranges (MacrocellRanges::coarser) the batches are first
// bounded a group at a time, and a group's batches only where the group
// could beat the value so far. The
// average skips the runs of ends in macrocells whose nodes are all 0
// (EmptySpace::for_zeros): a sample there is 0, and adding 0 leaves the
// sum unchanged (but for the sign of a zero sum, which c(v) does not see).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fathom/render.h"

#include "integrate/ray_span.h"
#include "integrate/simd_classify.h"
#include "render/empty_space.h"
#include "render/medium.h"

namespace fathom {

/// The scalar at segment ends j0 .. j0 + count − 1 (end j at
/// t_near + j·δ) into out[0 .. count − 1]: a batch with `simd`, else
/// GridSampler one at a time.
template <class T>
void scalar_ends(const ScalarMedium<T>& med, const RaySpan& sp, double delta, const simd::BatchSource* simd,
                 std::int64_t j0, int count, double* out) {
    if (simd != nullptr) {
        const simd::RayGrid rg{sp.p0, sp.dp, sp.t_near, delta, 0.0, 0};
        simd::interpolate_batch(*simd, rg, j0, count, out);
        return;
    }
    const SampleGrid grid{&sp, delta, 0.0, 0};
    for (int l = 0; l < count; ++l) out[l] = med.scalar(grid.at(j0 + l));
}

template <Model M, class T>
RayResult project(const ScalarMedium<T>& med, const RaySpan& sp, double h, const simd::BatchSource* simd,
                  const MacrocellRanges* ranges, const EmptySpace* zeros = nullptr, double empty_value = 0.0,
                  const MacrocellRanges* coarse = nullptr) {
    constexpr std::int64_t kGroup = 4;  // batches to a group (with coarse ranges)
    static_assert(M == Model::mip || M == Model::minip || M == Model::average);
    const std::int64_t n = segment_count(sp.length(), h);
    const double delta = sp.length() / static_cast<double>(n);
    alignas(64) double ends[simd::kBatch];
    double v = 0;
    // Ends j0 .. j1, kBatch at a time (end 0 first, in order: v starts at end 0).
    auto fold = [&](std::int64_t j0, std::int64_t j1) {
        for (; j0 <= j1; j0 += simd::kBatch) {
            const int count = static_cast<int>(std::min<std::int64_t>(simd::kBatch, j1 - j0 + 1));
            scalar_ends(med, sp, delta, simd, j0, count, ends);
            for (int l = 0; l < count; ++l) {
                const std::int64_t i = j0 + l;
                const double s = ends[l];
                if (i == 0) {
                    v = M == Model::average ? 0.5 * s : s;
                    continue;
                }
                if constexpr (M == Model::mip) v = std::max(v, s);
                if constexpr (M == Model::minip) v = std::min(v, s);
                if constexpr (M == Model::average) v += i == n ? 0.5 * s : s;
            }
        }
    };
    // Batch b: ends b·kBatch .. its last.
    auto fold_batch = [&](std::int64_t b) {
        fold(b * simd::kBatch, std::min(b * simd::kBatch + simd::kBatch - 1, n));
    };
    const std::int64_t batches = n / simd::kBatch + 1;
    if (M == Model::average && zeros != nullptr) {
        // The runs of ends in macrocells of zeros add nothing; the others
        // are folded in order.
        const RunFinder runs(*zeros, SampleGrid{&sp, delta, 0.0, 0});
        for (std::int64_t j = 0; j <= n;) {
            const RunFinder::Run run = runs.run_through(j, +1, n);
            if (!run.empty) fold(j, run.last);
            j = run.last + 1;
        }
    } else if (M == Model::average || ranges == nullptr) {
        fold(0, n);
    } else {
        // Best first: after batch 0, the batch whose macrocells could hold
        // the most extreme sample, until none can beat v. The largest (or
        // smallest) of a set does not depend on the order it is taken in
        // (a NaN at end 0 stays, later ones never win).
        fold_batch(0);
        // Nothing beats the lattice's extreme: a ray whose first batch
        // reaches it (MinIP's air around a CT) needs no bounds.
        if (M == Model::mip ? v >= ranges->highest() : v <= ranges->lowest())
            return RayResult{med.tf->color(v), 1.0};
        const double empty_bound = M == Model::mip ? empty_value : -empty_value;
        const SampleGrid grid{&sp, delta, 0.0, 0};  // end j at t_near + j·δ
        // A batch whose ends all lie before the ray's first point near a
        // macrocell of other values than `empty_value`, or after its last
        // (the pixel bounds over EmptySpace::for_value:
        // SampleGrid::outside_occupied), holds only `empty_value` (or ±0 for
        // 0): its bound is `empty_value`, without a box; so does a group.
        const auto [before, after] = sp.occupied_lo <= sp.occupied_hi
                                         ? grid.outside_occupied()
                                         : std::array<std::int64_t, 2>{-SampleGrid::kFar, SampleGrid::kFar};
        auto outside = [&](std::int64_t j0, std::int64_t j_last) { return j_last <= before || j0 >= after; };
        // take(b, bound) for batches b0 … b1 − 1: an upper bound on their
        // samples (MIP; minus a lower bound for MinIP). Batch b's box runs
        // from its first end's macrocell to the next batch's first end's
        // (its own last end's for the last batch): the computed positions
        // are monotone per axis along the ray, so the ends between lie in
        // it, and each batch's far end is the next one's near end, located once.
        auto bound_batches = [&](std::int64_t b0, std::int64_t b1, auto&& take) {
            std::array<std::int64_t, 3> near{};
            bool near_known = false;  // near: the macrocell of batch b's first end
            for (std::int64_t b = b0; b < b1; ++b) {
                const std::int64_t j0 = b * simd::kBatch, j1 = std::min(j0 + simd::kBatch, n);
                if (outside(j0, std::min(j0 + simd::kBatch - 1, n))) {
                    take(b, empty_bound);
                    near_known = false;
                    continue;
                }
                if (!near_known) near = ranges->macrocell(grid.at(j0));
                const auto far = ranges->macrocell(grid.at(j1));
                const auto r = ranges->bounds(near, far);
                take(b, M == Model::mip ? r[1] : -r[0]);
                near = far;
                near_known = true;
            }
        };
        if (coarse == nullptr) {
            // (every batch's bound in an array, scanned whole: the list
            // below measured 0.92–0.98× without groups, docs/performance.md
            // "Projections and isosurfaces")
            thread_local std::vector<double> bound;
            bound.resize(static_cast<std::size_t>(batches));
            bound_batches(1, batches,
                          [&](std::int64_t b, double x) { bound[static_cast<std::size_t>(b)] = x; });
            for (;;) {
                std::size_t best = 0;  // none
                double most = M == Model::mip ? v : -v;
                for (std::size_t b = 1; b < bound.size(); ++b)
                    if (bound[b] > most) {
                        most = bound[b];
                        best = b;
                    }
                if (best == 0) break;
                fold_batch(static_cast<std::int64_t>(best));
                bound[best] = -INFINITY;
            }
        } else {
            // Groups of kGroup batches first, each bounded by the coarse
            // macrocells of its box (from its first end to the next group's,
            // which holds its batches' boxes); a group's batches get their
            // own bounds when it is the best candidate. The candidates that
            // could beat v in a list: batches (b ≥ 1) and groups (b < 0:
            // the group from batch −1 − b).
            struct Candidate {
                double bound;
                std::int64_t b;
            };
            thread_local std::vector<Candidate> cand;
            cand.clear();
            auto add = [&](std::int64_t b, double x) {
                if (x > (M == Model::mip ? v : -v)) cand.push_back({x, b});
            };
            for (std::int64_t b0 = 1; b0 < batches; b0 += kGroup) {
                const std::int64_t b1 = std::min(b0 + kGroup, batches);
                const std::int64_t j0 = b0 * simd::kBatch, j1 = std::min(b1 * simd::kBatch, n);
                if (outside(j0, std::min(b1 * simd::kBatch - 1, n))) {
                    add(-1 - b0, empty_bound);
                    continue;
                }
                const auto r = coarse->bounds(coarse->macrocell(grid.at(j0)), coarse->macrocell(grid.at(j1)));
                add(-1 - b0, M == Model::mip ? r[1] : -r[0]);
            }
            for (;;) {
                std::size_t best = cand.size();  // none
                double most = M == Model::mip ? v : -v;
                for (std::size_t k = 0; k < cand.size(); ++k)
                    if (cand[k].bound > most) {
                        most = cand[k].bound;
                        best = k;
                    }
                if (best == cand.size()) break;
                const std::int64_t b = cand[best].b;
                // (in order: of equal bounds the nearest goes first, so that
                // a ray's batches are read from the volume in turn)
                cand.erase(cand.begin() + static_cast<std::ptrdiff_t>(best));
                if (b < 0)
                    bound_batches(-1 - b, std::min(-1 - b + kGroup, batches), add);
                else
                    fold_batch(b);
            }
        }
    }
    if constexpr (M == Model::average) v /= static_cast<double>(n);
    return RayResult{med.tf->color(v), 1.0};
}

}  // namespace fathom
