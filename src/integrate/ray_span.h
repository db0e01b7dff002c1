// The part of a ray inside the volume's box, in index space: the box is
// [0, nx−1] × [0, ny−1] × [0, nz−1] and p(t) = p0 + t·dp with t the world
// distance along the ray (dp = M⁻¹·d), eq. (1).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>

#include "fathom/math.h"

namespace fathom {

struct RaySpan {
    double t_near = 0, t_far = 0;
    Vec3 p0, dp;
    /// Jitter: where in its segment the point-sampled quadratures sample
    /// (fraction in [0, 1)), or < 0 to follow the sample_point setting.
    double sample_offset = -1.0;
    /// Every point of the ray in (or within PixelBounds::kMargin of) a
    /// non-empty macrocell has t in [occupied_lo, occupied_hi]
    /// (render/empty_space.h); the defaults bound nothing.
    double occupied_lo = -INFINITY, occupied_hi = INFINITY;
    [[nodiscard]] Vec3 at(double t) const { return p0 + dp * t; }
    [[nodiscard]] double length() const { return t_far - t_near; }
};

/// Intersects the ray (index-space origin p0, direction dp) with the closed
/// box, keeping t ≥ 0. Returns false when it misses or only grazes (L = 0).
inline bool intersect_box(const Vec3& p0, const Vec3& dp, const std::array<std::int64_t, 3>& dims,
                          RaySpan& out) {
    double t0 = 0.0, t1 = INFINITY;
    for (int a = 0; a < 3; ++a) {
        const double hi = static_cast<double>(dims[a] - 1);
        if (dp[a] == 0.0) {
            if (p0[a] < 0.0 || p0[a] > hi) return false;
            continue;
        }
        double ta = (0.0 - p0[a]) / dp[a];
        double tb = (hi - p0[a]) / dp[a];
        if (ta > tb) std::swap(ta, tb);
        t0 = std::max(t0, ta);
        t1 = std::min(t1, tb);
    }
    if (!(t1 > t0)) return false;
    out = {t0, t1, p0, dp};
    return true;
}

/// The uniform division of eq. (8): n = max(1, ceil(L/h)).
inline std::int64_t segment_count(double length, double h) {
    return std::max<std::int64_t>(1, static_cast<std::int64_t>(std::ceil(length / h)));
}

}  // namespace fathom
