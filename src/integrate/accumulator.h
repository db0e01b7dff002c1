// Accumulators: compose per-segment (transmittance t_i, radiance C_i) pairs
// front to back (eq. (10), with early termination) or back to front
// (eq. (11)). The integrators hand segments in by index i = 1..n.
#pragma once

#include <algorithm>
#include <cmath>
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

/// Depth outputs of one ray on the uniform segment grid (segment i spans
/// [t0 + (i − 1)·δ, t0 + i·δ]): the expected termination depth
/// Σ T_{i−1}·α_i·t_i / (1 − T), t_i the segment's midpoint (the termination
/// density of docs/theory.md, discretised), and the start of the first
/// segment with α > 0.
struct DepthTrack {
    double t0, delta;
    double weighted = 0.0;  // Σ T·α·t (front to back) or its back-to-front recurrence
    double first = INFINITY;
    void add(std::int64_t i, double alpha, double T_before) {
        if (!(alpha > 0.0)) return;
        weighted += T_before * alpha * (t0 + (static_cast<double>(i) - 0.5) * delta);
        first = std::min(first, t0 + static_cast<double>(i - 1) * delta);
    }
    void add_back(std::int64_t i, double alpha) {  // D ← α·t + (1 − α)·D
        if (!(alpha > 0.0)) return;
        weighted = alpha * (t0 + (static_cast<double>(i) - 0.5) * delta) + (1.0 - alpha) * weighted;
        first = std::min(first, t0 + static_cast<double>(i - 1) * delta);
    }
    void finish(RayResult& r) const {
        r.depth = r.alpha > 0.0 ? weighted / r.alpha : INFINITY;
        r.first_hit = first;
    }
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
                    Skip&& skip = {}, DepthTrack* track = nullptr) {
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
                if (track) track->add(i, 1.0 - s.transmittance, T);
                T *= s.transmittance;
                if (T < termination) {  // eq. (10): drop the rest and the background
                    r.alpha = 1.0 - T;
                    if (track) track->finish(r);
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
                if (track) track->add_back(i, 1.0 - s.transmittance);
                T *= s.transmittance;
            }
        }
    }
    r.alpha = 1.0 - T;
    if (track) track->finish(r);
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
