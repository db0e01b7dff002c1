// Scene files (fathom-scene/1, SPEC §7): a volume (scalar with a transfer
// function, or pre-classified density/color grids), a camera and render
// settings, loaded and ready to render.
#pragma once

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

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
    /// The same, handed this scene's scalar volume (left empty): a large one
    /// may go into bricks in place (Renderer(Volume&&, ...)). Pre-classified
    /// grids are shared as by renderer().
    [[nodiscard]] Renderer take_renderer();
};

/// Overrides of a scene's render settings: the render flags of `fathom
/// render` (SPEC §8, docs/cli.md), each replacing the scene's value when set
/// (empty strings and vectors, unset optionals and false flags keep it).
/// The CLI and the Python module both apply them with apply_overrides, so
/// a flag means the same everywhere.
struct SceneOverrides {
    std::optional<int> width, height, threads;
    /// Names as in scene files: model, integrator, order, sample_point,
    /// step_unit ("voxel" or "world"), gradient ("on-the-fly" or "precomputed").
    std::string model, integrator, order, sample_point, step_unit, gradient;
    std::optional<double> step, termination;
    bool jitter = false;         // turns jitter on
    bool no_skip_empty = false;  // turns empty-space skipping off
    bool no_simd = false;        // turns SIMD classification off
    bool no_packets = false;     // traces rays one by one (RenderSettings::packets)
    bool no_bricks = false;      // keeps the volume x-fastest (RenderSettings::brick_min_bytes)
    bool shade = false;          // turns shading on
    std::optional<std::uint32_t> jitter_seed;
    /// Isosurfaces, each VALUE[,R,G,B[,OPACITY]]: replace the scene's and
    /// select the isosurface model unless `model` is set.
    std::vector<std::vector<double>> isos;
    std::vector<double> phong;                     // AMBIENT,DIFFUSE,SPECULAR,SHININESS (turns shading on)
    std::vector<double> crop;                      // X0,Y0,Z0,X1,Y1,Z1 in world coordinates
    std::vector<std::vector<double>> clip_planes;  // each PX,PY,PZ,NX,NY,NZ; replace the scene's
    std::vector<double> background;                // R,G,B
    bool transparent = false;                      // background "transparent"
};

/// Applies the overrides to `s` and validates the result. A wrong count of
/// numbers or an unknown name throws Error(subject, reason) with the reason
/// naming the CLI flag (e.g. "--crop expects X0,Y0,Z0,X1,Y1,Z1 ..."); settings
/// out of range throw RenderSettings::validate's Error.
void apply_overrides(RenderSettings& s, const SceneOverrides& o, const std::string& subject);

/// Loads a scene file; relative paths are relative to its directory.
Scene load_scene(const std::filesystem::path& path);
/// Parses scene JSON text; relative paths resolve against base_dir and
/// errors name `subject`.
Scene parse_scene(std::string_view json_text, const std::filesystem::path& base_dir,
                  const std::string& subject);

}  // namespace fathom
