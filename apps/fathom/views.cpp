// fathom views: renders a scene from many directions into a NeRF-style view
// set (SPEC §9) with train and test splits: a reconstruction benchmark whose
// answer is known (docs/reverse-rendering.md).
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <numbers>

#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/scene.h"

#include "commands.h"
#include "scene_args.h"

namespace fathom::cli {
namespace {

namespace fs = std::filesystem;

struct ViewsArgs {
    SceneArgs scene;
    std::string output;
    int train = 64, test = 16;
    bool quiet = false;
};

/// n directions spread evenly over the sphere (a Fibonacci lattice), turned
/// by `turn` of the golden angle so that two sets with different turns
/// interleave; as orbit (azimuth, elevation) in degrees.
std::vector<std::array<double, 2>> sphere_directions(int n, double turn) {
    const double golden = std::numbers::pi * (3.0 - std::sqrt(5.0));
    std::vector<std::array<double, 2>> out;
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - (2.0 * i + 1.0) / n;
        const double az = std::fmod((i + turn) * golden, 2.0 * std::numbers::pi);
        out.push_back({az * 180.0 / std::numbers::pi, std::asin(z) * 180.0 / std::numbers::pi});
    }
    return out;
}

/// The world-space axis-aligned box of a volume's lattice.
std::array<Vec3, 2> world_box(const Volume& v) {
    Vec3 lo{INFINITY, INFINITY, INFINITY}, hi{-INFINITY, -INFINITY, -INFINITY};
    for (int c = 0; c < 8; ++c) {
        const Vec3 ijk{(c & 1) ? static_cast<double>(v.dims()[0] - 1) : 0.0,
                       (c & 2) ? static_cast<double>(v.dims()[1] - 1) : 0.0,
                       (c & 4) ? static_cast<double>(v.dims()[2] - 1) : 0.0};
        const Vec3 p = v.index_to_world(ijk);
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    }
    return {lo, hi};
}

void run_views(const ViewsArgs& a) {
    if (a.train < 1 || a.train > 10000 || a.test < 0 || a.test > 10000)
        throw UsageError("--train must be in 1..10000 and --test in 0..10000");
    Scene scene = a.scene.load("views");
    if (scene.camera.projection != Projection::perspective)
        throw UsageError("views needs a perspective camera (NeRF sets have a field of view)");
    scene.settings.transparent = true;  // alpha is coverage (SPEC §9)
    const Bounds b = volume_bounds(scene.volume);
    const double distance = length(scene.camera.position - b.center) / b.radius;
    const auto box = world_box(scene.volume);
    const Renderer renderer = scene.take_renderer();  // the volume is not needed after this
    const RenderSettings& s = scene.settings;
    const double fov_y = scene.camera.fov_y_deg * std::numbers::pi / 180.0;
    const double angle_x = 2.0 * std::atan(std::tan(fov_y / 2.0) * s.width / s.height);
    const fs::path out = a.output;
    auto write_set = [&](const std::string& split, int n, double turn) {
        nlohmann::json frames = nlohmann::json::array();
        fs::create_directories(out / split);
        const auto dirs = sphere_directions(n, turn);
        for (int i = 0; i < n; ++i) {
            Camera cam = Camera::orbit(dirs[i][0], dirs[i][1], distance, b.center, b.radius);
            cam.fov_y_deg = scene.camera.fov_y_deg;
            char name[32];
            std::snprintf(name, sizeof name, "r_%03d.png", i);
            write_image(out / split / name, renderer.render(cam), true);
            const auto m = cam.to_matrix();
            nlohmann::json rows = nlohmann::json::array();
            for (int r = 0; r < 4; ++r) rows.push_back({m[4 * r], m[4 * r + 1], m[4 * r + 2], m[4 * r + 3]});
            frames.push_back({{"file_path", split + "/" + name}, {"transform_matrix", rows}});
            if (!a.quiet) std::fprintf(stderr, "\r%s %d/%d", split.c_str(), i + 1, n);
        }
        if (!a.quiet) std::fputs("\n", stderr);
        const nlohmann::json j{
            {"camera_angle_x", angle_x},
            {"fathom_bounds", {{box[0].x, box[0].y, box[0].z}, {box[1].x, box[1].y, box[1].z}}},
            {"frames", frames}};
        write_text_file(out / ("transforms_" + split + ".json"), j.dump(2) + "\n");
    };
    write_set("train", a.train, 0.0);
    if (a.test > 0) write_set("test", a.test, 0.5);
}

}  // namespace

void add_views_command(CLI::App& app) {
    auto* cmd = app.add_subcommand(
        "views", "Render a scene from directions spread over the sphere into a NeRF view set (train/test)");
    auto a = std::make_shared<ViewsArgs>();
    a->scene.add_to(cmd);
    cmd->add_option("-o,--output", a->output,
                    "Output folder: train/ and test/ PNGs (RGBA, straight alpha) and transforms_*.json")
        ->required();
    cmd->add_option("--train", a->train, "Number of training views (default 64)");
    cmd->add_option("--test", a->test, "Number of held-out views, between the training ones (default 16)");
    cmd->add_flag("-q,--quiet", a->quiet, "No progress");
    cmd->callback([a] { run_views(*a); });
}

}  // namespace fathom::cli
