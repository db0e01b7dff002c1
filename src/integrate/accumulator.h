// Accumulators: compose per-segment (transmittance t_i, radiance C_i) pairs
// front to back (eq. (10), with early termination) or back to front
// (eq. (11)). The integrators hand segments in by index i = 1..n.
#pragma once

#include <algorithm>
#include <cstdint>

#include "fathom/math.h"
#include "fathom/render.h"

namespace fathom {

/// What a medium gives at a point.
struct MediumSample {
    double sigma = 0;  // extinction σ (1/world unit)
    Rgb source{};      // g: σ·c or q
};

struct Segment {
    double transmittance;  // t_i = 1 − α_i
    Rgb radiance;          // C_i
};

/// Without empty-space skipping: evaluate every segment.
struct NoSkip {
    std::int64_t operator()(std::int64_t /*i*/, int /*dir*/) { return -(std::int64_t{1} << 62); }
};

/// skip(i, dir) → k: when k > 0, segments i, i + dir, …, i + (k − 1)·dir are
/// known to have transmittance exactly 1 and radiance exactly 0, so they
/// would leave both accumulators unchanged and are not evaluated
/// (render/empty_space.h); when k < 0, the next −k segments are evaluated
/// without asking again. k = 0 is not allowed.
template <class SegmentFn, class Skip = NoSkip>
RayResult composite(std::int64_t n, Order order, double termination, const Rgb& bg, SegmentFn&& segment,
                    Skip&& skip = {}) {
    RayResult r;
    double T = 1.0;
    if (order == Order::front_to_back) {
        for (std::int64_t i = 1; i <= n;) {
            const std::int64_t k = skip(i, +1);
            if (k > 0) {
                i += k;
                continue;
            }
            for (const std::int64_t end = std::min(n, i - k - 1); i <= end; ++i) {
                const Segment s = segment(i);
                for (int c = 0; c < 3; ++c) r.radiance[c] += T * s.radiance[c];
                T *= s.transmittance;
                if (T < termination) {  // eq. (10): drop the rest and the background
                    r.alpha = 1.0 - T;
                    return r;
                }
            }
        }
        for (int c = 0; c < 3; ++c) r.radiance[c] += T * bg[c];
    } else {
        r.radiance = bg;
        for (std::int64_t i = n; i >= 1;) {
            const std::int64_t k = skip(i, -1);
            if (k > 0) {
                i -= k;
                continue;
            }
            for (const std::int64_t end = std::max<std::int64_t>(1, i + k + 1); i >= end; --i) {
                const Segment s = segment(i);
                for (int c = 0; c < 3; ++c) r.radiance[c] = s.transmittance * r.radiance[c] + s.radiance[c];
                T *= s.transmittance;
            }
        }
    }
    r.alpha = 1.0 - T;
    return r;
}

/// The model's attenuation and source (SPEC §1): absorption drops g,
/// emission drops σ_a.
template <Model M>
inline void apply_model(double& sigma_a, Rgb& g) {
    if constexpr (M == Model::absorption) g = {0, 0, 0};
    if constexpr (M == Model::emission) sigma_a = 0.0;
}

}  // namespace fathom
