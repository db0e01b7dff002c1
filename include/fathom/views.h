// Multi-view image sets (SPEC §9): a NeRF-style transforms.json with its
// images, the input of reverse rendering (docs/reverse-rendering.md).
#pragma once

#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "fathom/camera.h"
#include "fathom/image.h"
#include "fathom/math.h"

namespace fathom {

struct View {
    std::filesystem::path file;
    Camera camera;  // perspective, fov_y from camera_angle_x and the image's aspect
    Image image;    // linear RGBA, straight alpha (coverage)
};

struct ViewSet {
    double camera_angle_x = 0;  // horizontal field of view, radians
    std::vector<View> views;
    /// The world box of the volume, when the set carries one
    /// ("fathom_bounds", written by `fathom views`).
    std::optional<std::array<Vec3, 2>> bounds;
    [[nodiscard]] int width() const { return views.empty() ? 0 : views.front().image.width; }
    [[nodiscard]] int height() const { return views.empty() ? 0 : views.front().image.height; }
};

/// Reads transforms.json and its PNG images (file_path relative to the JSON
/// file; ".png" is appended when the path has no extension). Every image
/// must have the same size. Errors name the file and the problem.
ViewSet read_view_set(const std::filesystem::path& transforms);

}  // namespace fathom
