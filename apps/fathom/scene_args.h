// The scene part of the command line, shared by `render` and `bench`: a
// scene file or --volume with --tf/--preset/--orbit, and the render flags
// that override it (SPEC §8).
#pragma once

#include <string>
#include <vector>

#include "fathom/scene.h"

#include "commands.h"

namespace fathom::cli {

struct SceneArgs {
    std::string scene, volume, series, grid, tf, preset, orbit, background, crop, phong;
    std::vector<std::string> clip_planes, isos;
    int width = 0, height = 0, threads = 0;
    double step = 0, termination = 0;
    std::uint32_t jitter_seed = 0;
    /// The flags that need no parsing (names and switches), bound directly;
    /// load() adds the numbers and lists parsed from the other flags.
    SceneOverrides overrides;
    CLI::Option* o_seed{};
    CLI::Option *o_width{}, *o_height{}, *o_step{}, *o_termination{}, *o_threads{};

    /// Registers the positional SCENE and every scene/render flag on `cmd`.
    void add_to(CLI::App* cmd);
    /// Loads the scene (file or flags) and applies the overrides; usage
    /// mistakes throw UsageError, bad files fathom::Error.
    [[nodiscard]] Scene load(const std::string& command) const;
};

/// --background of the fitters: "white", "black" or "R,G,B"; UsageError otherwise.
Rgb parse_background(const std::string& text);

/// "1,2.5,3" → numbers; UsageError naming the flag otherwise.
std::vector<double> parse_numbers(const std::string& text, const std::string& flag);

}  // namespace fathom::cli
