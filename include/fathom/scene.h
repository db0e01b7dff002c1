// Scene files (fathom-scene/1, SPEC §7): a volume (scalar with a transfer
// function, or pre-classified density/color grids), a camera and render
// settings, loaded and ready to render.
#pragma once

#include <filesystem>
#include <optional>
#include <string>
#include <string_view>

#include "fathom/camera.h"
#include "fathom/render.h"
#include "fathom/transfer_function.h"
#include "fathom/volume.h"

namespace fathom {

struct Scene {
    std::string name;             // the scene file (for messages)
    Volume volume;                // the scalar volume, or the density grid when pre-classified
    std::optional<Volume> color;  // set for pre-classified grids
    TransferFunction tf;          // unused when pre-classified
    Camera camera;
    RenderSettings settings;

    [[nodiscard]] bool preclassified() const { return color.has_value(); }
    /// A renderer over this scene's medium with its settings (or others).
    [[nodiscard]] Renderer renderer() const { return renderer(settings); }
    [[nodiscard]] Renderer renderer(const RenderSettings& s) const;
};

/// Loads a scene file; relative paths are relative to its directory.
Scene load_scene(const std::filesystem::path& path);
/// Parses scene JSON text; relative paths resolve against base_dir and
/// errors name `subject`.
Scene parse_scene(std::string_view json_text, const std::filesystem::path& base_dir,
                  const std::string& subject);

}  // namespace fathom
