// SIMD projection of the pixel bounds' boxes (EmptySpace::pixel_bounds,
// docs/performance.md "Empty-space skipping"): several border macrocells'
// boxes at once, each lane performing the scalar projection's operations in
// the same order, so the footprints are the same.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

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

}  // namespace fathom::simd
