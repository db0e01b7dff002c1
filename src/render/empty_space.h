// Exact empty-space skipping (docs/performance.md "Empty-space skipping").
//
// The lattice's cells are grouped into macrocells of c³ cells (c = 2^shift). A
// macrocell holds the range [min, max] of its nodes (its boundary nodes
// included), which bounds every trilinear sample inside it. It is *empty*
// when the medium is exactly zero over that range under the frame's model:
// σ = 0 (absorption), g = 0 (emission), both (emission–absorption); for
// pre-classified grids, when every density node is exactly 0.
//
// A sample inside an empty macrocell gives a segment with transmittance
// exactly 1 and radiance exactly 0, which leaves both accumulators unchanged
// bit for bit; so does a pre-integrated segment whose two ends lie in one
// empty macrocell (the linear ramp between them stays in its range). The
// integrators therefore skip such runs of samples without changing the
// image, and keep the uniform segment division of eq. (8): a run ends on the
// segment grid, at the last sample whose *computed* position still falls
// into the macrocell. Sample positions p0 + dp·t with t = t_near + x·δ are
// monotone in x per axis (IEEE rounding is monotone), so the samples
// between two samples of one macrocell are in it too; the run's end is
// estimated from the ray's exit from the macrocell's box and then verified
// on the computed position.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fathom/math.h"
#include "fathom/render.h"
#include "fathom/transfer_function.h"
#include "fathom/volume.h"

#include "integrate/ray_span.h"

// Small functions on the per-sample path that GCC otherwise leaves out of line.
#define FATHOM_INLINE inline __attribute__((always_inline))

namespace fathom {

/// The medium under model m is exactly zero for every scalar in [a, b]:
/// σ = 0 (absorption), g = 0 (emission: g = σ·c is zero with σ or c, q for
/// an associated emission), both (emission–absorption). Conservative.
inline bool medium_zero_on(const Classifier& tf, Model m, double a, double b) {
    const bool no_sigma = tf.sigma_zero_on(a, b);
    if (m == Model::absorption) return no_sigma;
    if (tf.associated()) return (m == Model::emission || no_sigma) && tf.color_zero_on(a, b);
    return no_sigma || (m == Model::emission && tf.color_zero_on(a, b));
}

class EmptySpace {
public:
    EmptySpace() = default;
    /// A scalar volume classified by `tf` under model `m`, macrocells of
    /// 2^shift cells per edge.
    static EmptySpace for_scalar(const Volume& v, const Classifier& tf, Model m, int shift, int threads);
    /// Pre-classified grids: empty where every density node is exactly 0.
    static EmptySpace for_density(const Volume& density, int shift, int threads);

    /// True when at least one macrocell is empty (else skipping is pointless).
    [[nodiscard]] bool any() const { return any_; }
    [[nodiscard]] double empty_fraction() const;

    /// Macrocells are grouped 4³ into coarse cells, empty when all of theirs
    /// are: a ray crosses large empty regions in few steps.
    static constexpr int kCoarse = 2;

    /// The macrocell (level 0) or coarse cell (level 1) of a position, the
    /// cell chosen as GridSampler picks it.
    [[nodiscard]] FATHOM_INLINE std::array<std::int64_t, 3> cell(const Vec3& p, int level) const {
        const int sh = shift_ + level * kCoarse;
        return {axis_cell(p.x, 0) >> sh, axis_cell(p.y, 1) >> sh, axis_cell(p.z, 2) >> sh};
    }
    [[nodiscard]] FATHOM_INLINE std::array<std::int64_t, 3> macrocell(const Vec3& p) const {
        return cell(p, 0);
    }
    [[nodiscard]] FATHOM_INLINE bool empty(const std::array<std::int64_t, 3>& m, int level = 0) const {
        const auto& d = dims_[level];
        return empty_[level][static_cast<std::size_t>(m[0] + d[0] * (m[1] + d[1] * m[2]))] != 0;
    }

    /// The ray parameter where the ray leaves (dir = +1) or enters
    /// (dir = −1) cell m's box at `level`; inv_dp = 1/dp per axis (an
    /// estimate: callers verify on computed positions).
    [[nodiscard]] FATHOM_INLINE double box_exit(const RaySpan& sp, const Vec3& inv_dp,
                                                const std::array<std::int64_t, 3>& m, int dir,
                                                int level) const {
        const int sh = shift_ + level * kCoarse;
        double t = dir > 0 ? INFINITY : -INFINITY;
        for (int a = 0; a < 3; ++a) {
            if (sp.dp[a] == 0.0) continue;
            const double lo = static_cast<double>(m[a] << sh);
            const double hi = static_cast<double>(std::min((m[a] + 1) << sh, nodes_[a] - 1));
            const bool up = (sp.dp[a] > 0.0) == (dir > 0);
            const double ta = ((up ? hi : lo) - sp.p0[a]) * inv_dp[a];
            t = dir > 0 ? std::min(t, ta) : std::max(t, ta);
        }
        return t;
    }

private:
    /// Macrocells whose node range [lo, hi] satisfies empty(lo, hi) are empty.
    template <class Empty>
    static EmptySpace from_ranges(const Volume& v, int shift, int threads, Empty&& empty);
    void build_coarse();
    [[nodiscard]] FATHOM_INLINE std::int64_t axis_cell(double p, int a) const {
        const double x = std::clamp(p, 0.0, static_cast<double>(nodes_[a] - 1));
        return std::min(static_cast<std::int64_t>(x), nodes_[a] - 2);
    }

    int shift_ = 3;
    std::array<std::int64_t, 3> nodes_{};
    std::array<std::int64_t, 3> dims_[2]{};  // macrocells, coarse cells
    std::vector<std::uint8_t> empty_[2];     // per level
    bool any_ = false;
};

/// Sample positions on the segment grid: index j sits at
/// t_near + (j − first + offset)·δ (first = 1 and the in-segment offset for
/// the point samples of segments 1..n; first = 0, offset = 0 for the
/// segment ends 0..n of pre-integration). The integrators sample through
/// this, so the run finder sees the very positions they sample.
struct SampleGrid {
    const RaySpan* span;
    double delta, offset;
    std::int64_t first;
    [[nodiscard]] FATHOM_INLINE double t(std::int64_t j) const {
        return span->t_near + (static_cast<double>(j - first) + offset) * delta;
    }
    [[nodiscard]] FATHOM_INLINE Vec3 at(std::int64_t j) const { return span->at(t(j)); }
};

/// Walks runs of samples through macrocells for one ray: run(j, dir, limit)
/// finds the macrocell of sample j and the farthest sample index k (from j
/// towards `limit` in direction dir = ±1) still in it, so that samples j..k
/// all lie in that macrocell.
class RunFinder {
public:
    struct Run {
        std::int64_t last;  // k
        bool empty;         // the macrocell is empty
    };

    RunFinder(const EmptySpace& es, SampleGrid grid)
        : es_(es),
          g_(grid),
          inv_dp_{1.0 / grid.span->dp.x, 1.0 / grid.span->dp.y, 1.0 / grid.span->dp.z},
          inv_delta_(1.0 / grid.delta) {}

    Run run(std::int64_t j, int dir, std::int64_t limit) const {
        const Vec3 pj = g_.at(j);
        const auto m = es_.macrocell(pj);
        if (!es_.empty(m)) return {last_in(m, 0, j, dir, limit), false};
        const auto c = es_.cell(pj, 1);
        if (es_.empty(c, 1)) return {last_in(c, 1, j, dir, limit), true};
        return {last_in(m, 0, j, dir, limit), true};
    }

private:
    // The farthest index from j towards limit whose position is in cell m
    // at `level` (sample j is in it).
    [[nodiscard]] FATHOM_INLINE std::int64_t last_in(const std::array<std::int64_t, 3>& m, int level,
                                                     std::int64_t j, int dir, std::int64_t limit) const {
        const double tb = es_.box_exit(*g_.span, inv_dp_, m, dir, level);
        // the fractional index of the box exit (inverse of SampleGrid::t)
        double x = (tb - g_.span->t_near) * inv_delta_ - g_.offset + static_cast<double>(g_.first);
        std::int64_t k = limit;
        if (std::isfinite(x)) {
            x = dir > 0 ? std::floor(x) : std::ceil(x);
            const double lo = static_cast<double>(std::min(j, limit)),
                         hi = static_cast<double>(std::max(j, limit));
            k = static_cast<std::int64_t>(std::clamp(x, lo, hi));
        }
        // Verify on the computed positions (rounding can move the last one out).
        while (k != j && es_.cell(g_.at(k), level) != m) k -= dir;
        return k;
    }

    const EmptySpace& es_;
    SampleGrid g_;
    Vec3 inv_dp_;
    double inv_delta_;
};

}  // namespace fathom
