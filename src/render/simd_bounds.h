// SIMD projection of the pixel bounds' boxes (EmptySpace::pixel_bounds,
// docs/performance.md "Empty-space skipping"): several border macrocells'
// boxes at once, each lane performing the scalar projection's operations in
// the same order, so the footprints are the same.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>

#include "fathom/math.h"

namespace fathom::simd {

/// How a box of lattice points projects onto the image: camera coordinates
/// (along right, up, forward) of lattice point q are c0 + Σ_a q_a·col[a];
/// pixel coordinates of a camera point c are px = c.x·s·scale_x + bx and
/// py = by − c.y·s·scale_y with s = 1/c.z (perspective) or 1.
struct BoxProjection {
    Vec3 c0;
    std::array<Vec3, 3> col;
    bool perspective = true;
    double scale_x = 1, scale_y = 1, bx = 0, by = 0;
    /// The boxes: macrocell m (x-fastest index among dims) spans lattice
    /// points m·2^shift … min((m + 1)·2^shift, nodes − 1) per axis, widened
    /// by margin.
    int shift = 2;
    double margin = 0;
    std::array<std::int64_t, 3> dims{}, nodes{};
};

/// Per box, before rounding: the rectangle its 8 corners project into and
/// the range of t (camera depth, or the distance from the eye) over it.
struct BoxImages {
    double *x0, *x1, *y0, *y1, *t0, *t1;
};

/// Projects the boxes of macrocells index[0 … count) into out[0 … count)
/// with the best target (the values EmptySpace::pixel_bounds computed per
/// box before). out's arrays hold count rounded up to a multiple of 8.
void project_boxes(const BoxProjection& p, const std::uint32_t* index, std::size_t count,
                   const BoxImages& out);

/// How a box's image becomes its footprint on a width × height image: the
/// pixels whose centres fall in the image widened by pixel_slack, and its
/// range of t widened by t_slack and rounded outwards to floats.
struct FootprintRule {
    int width = 1, height = 1;
    double pixel_slack = 0, t_slack = 0;
};

/// Footprints (structure of arrays): inclusive pixel rectangles clipped to
/// the image (x0 > x1 or y0 > y1: off it) and bounds on t there.
struct Footprints {
    std::int32_t *x0, *x1, *y0, *y1;
    float *lo, *hi;
};

/// x rounded to a float no larger (down) or no smaller (up). Beyond the
/// floats' range (where a conversion would be undefined) what rounding to
/// the nearest float and stepping give: down, FLT_MAX above it (∞ at ∞)
/// and −∞ below it; up, ∞ above it and −FLT_MAX below it (−∞ at −∞).
inline float round_float(double x, bool down) {
    constexpr double kMax = std::numeric_limits<float>::max();
    if (x > kMax) return down && !std::isinf(x) ? std::numeric_limits<float>::max() : INFINITY;
    if (x < -kMax) return !down && !std::isinf(x) ? -std::numeric_limits<float>::max() : -INFINITY;
    const auto f = static_cast<float>(x);
    if (down && static_cast<double>(f) > x) return std::nextafter(f, -INFINITY);
    if (!down && static_cast<double>(f) < x) return std::nextafter(f, INFINITY);
    return f;
}

/// The footprint of one box's image (x0 … t1 as project_boxes gives them):
/// the whole image and (−∞, ∞) where any of them is not finite. The
/// reference for footprints() (and the rule EmptySpace::pixel_bounds
/// follows), one box at a time.
inline void footprint_of(const FootprintRule& r, const double* image, std::int32_t* rect, float* t) {
    const double x0 = image[0], x1 = image[1], y0 = image[2], y1 = image[3], t0 = image[4], t1 = image[5];
    if (!std::isfinite(x0 + x1 + y0 + y1 + t0 + t1)) {  // no bound
        rect[0] = rect[2] = 0;
        rect[1] = r.width - 1;
        rect[3] = r.height - 1;
        t[0] = -INFINITY;
        t[1] = INFINITY;
        return;
    }
    auto clip = [](double v, int n) { return static_cast<int>(std::clamp(v, -1.0, static_cast<double>(n))); };
    rect[0] = std::max(0, clip(std::ceil(x0 - r.pixel_slack), r.width));
    rect[1] = std::min(r.width - 1, clip(std::floor(x1 + r.pixel_slack), r.width));
    rect[2] = std::max(0, clip(std::ceil(y0 - r.pixel_slack), r.height));
    rect[3] = std::min(r.height - 1, clip(std::floor(y1 + r.pixel_slack), r.height));
    t[0] = round_float(t0 - r.t_slack, true);
    t[1] = round_float(t1 + r.t_slack, false);
}

/// footprint_of for boxes 0 … count − 1 of `in`, in vectors with the best
/// target: the same values. out's arrays hold count rounded up to a
/// multiple of 16.
void footprints(const FootprintRule& r, const BoxImages& in, std::size_t count, const Footprints& out);

/// Draws footprints 0 … count − 1 into bounds of `width` pixels a row:
/// lo[p] = min(lo[p], f.lo) and hi[p] = max(hi[p], f.hi) over each
/// footprint's pixels (std::min's and std::max's choices), in vectors along
/// its rows with the best target.
void draw_footprints(const Footprints& f, std::size_t count, int width, float* lo, float* hi);

}  // namespace fathom::simd
