// Image: a float RGBA film, row 0 at the top (SPEC §4, §6). Color is linear
// radiance; A is the pixel's opacity α.
#pragma once

#include <cstddef>
#include <vector>

namespace fathom {

struct Image {
    int width = 0;
    int height = 0;
    std::vector<float> rgba;  // 4 floats per pixel, row-major, row 0 at the top
    /// Depth outputs, one float per pixel, when rendered with depth_outputs:
    /// expected termination depth and first-hit depth (world units along
    /// the ray; +inf where nothing is hit).
    std::vector<float> depth, first_hit;

    Image() = default;
    Image(int w, int h)
        : width(w), height(h), rgba(static_cast<std::size_t>(w) * static_cast<std::size_t>(h) * 4, 0.0f) {}

    float* pixel(int x, int y) {
        return &rgba[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                      static_cast<std::size_t>(x)) *
                     4];
    }
    [[nodiscard]] const float* pixel(int x, int y) const {
        return &rgba[(static_cast<std::size_t>(y) * static_cast<std::size_t>(width) +
                      static_cast<std::size_t>(x)) *
                     4];
    }
};

}  // namespace fathom
