// fathom render: a scene file, or a volume with a transfer function and an
// orbit, to a PFM, PNG or EXR image (SPEC §8). Flags override the scene.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <numbers>
#include <vector>

#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/scene.h"
#include "fathom/video.h"

#include "commands.h"
#include "scene_args.h"

namespace fathom::cli {
namespace {

namespace fs = std::filesystem;

struct RenderArgs {
    SceneArgs scene;
    std::string output;
    bool quiet = false;
    int orbit_frames = 0;
    std::string transforms;
    std::string depth_out, first_hit_out;
    bool depth_channels = false;
    std::string video;
    int fps = 24;
};

/// One float per pixel as a gray image (the value in R, G and B).
Image gray(const Image& like, const std::vector<float>& v) {
    Image g(like.width, like.height);
    for (std::size_t i = 0; i < v.size(); ++i) {
        for (int c = 0; c < 3; ++c) g.rgba[4 * i + static_cast<std::size_t>(c)] = v[i];
        g.rgba[4 * i + 3] = 1.0f;
    }
    return g;
}

void check_float_output(const std::string& flag, const std::string& path) {
    std::string ext = fs::path(path).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext != ".pfm" && ext != ".exr")
        throw UsageError(flag + " " + path + ": depths need a float image: .pfm or .exr");
}

/// OUT.ext → OUT_007.ext for frame 7.
fs::path frame_path(const fs::path& out, int f) {
    char num[16];
    std::snprintf(num, sizeof num, "_%03d", f);
    return out.parent_path() / (out.stem().string() + num + out.extension().string());
}

/// The NeRF transforms.json of SPEC §9 for the frames written.
void write_transforms(const fs::path& json_path, const Scene& scene, const std::vector<fs::path>& files,
                      const std::vector<Camera>& cams) {
    const RenderSettings& s = scene.settings;
    const double fov_y = scene.camera.fov_y_deg * std::numbers::pi / 180.0;
    const double angle_x = 2.0 * std::atan(std::tan(fov_y / 2.0) * s.width / s.height);
    nlohmann::json frames = nlohmann::json::array();
    const fs::path base = fs::absolute(json_path).parent_path();
    for (std::size_t i = 0; i < files.size(); ++i) {
        const auto m = cams[i].to_matrix();
        nlohmann::json rows = nlohmann::json::array();
        for (int r = 0; r < 4; ++r) rows.push_back({m[4 * r], m[4 * r + 1], m[4 * r + 2], m[4 * r + 3]});
        frames.push_back({{"file_path", fs::relative(fs::absolute(files[i]), base).generic_string()},
                          {"transform_matrix", rows}});
    }
    const nlohmann::json j{{"camera_angle_x", angle_x}, {"frames", frames}};
    write_text_file(json_path, j.dump(2) + "\n");
}

// A progress line on stderr for renders that take over a second, only on a terminal.
class Progress {
public:
    explicit Progress(bool enabled) : enabled_(enabled && isatty(STDERR_FILENO)) {}
    ~Progress() {
        if (shown_) std::fputs("\r\033[K", stderr);
    }
    Progress(const Progress&) = delete;
    Progress& operator=(const Progress&) = delete;
    void operator()(int done, int total) {
        if (!enabled_) return;
        const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
        if (secs < 1.0) return;
        std::lock_guard lock(mutex_);
        const int pct = static_cast<int>(100.0 * done / total);
        if (pct == last_) return;
        last_ = pct;
        shown_ = true;
        std::fprintf(stderr, "\rrendering %3d%%  %.1f s", pct, secs);
        std::fflush(stderr);
    }

private:
    bool enabled_;
    bool shown_ = false;
    int last_ = -1;
    std::mutex mutex_;
    std::chrono::steady_clock::time_point start_ = std::chrono::steady_clock::now();
};

void run_render(const RenderArgs& a) {
    std::string ext = fs::path(a.output).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext != ".pfm" && ext != ".png" && ext != ".exr")
        throw UsageError("-o " + a.output + ": the output must end in .pfm, .png or .exr");
    if (a.orbit_frames < 0 || a.orbit_frames > 100000)
        throw UsageError("--orbit-frames must be in 0..100000");
    if (!a.transforms.empty() && a.orbit_frames == 0)
        throw UsageError("--transforms goes with --orbit-frames");
    if (!a.video.empty()) {
        if (a.orbit_frames == 0) throw UsageError("--video goes with --orbit-frames");
        std::string vext = fs::path(a.video).extension().string();
        std::transform(vext.begin(), vext.end(), vext.begin(),
                       [](unsigned char c) { return std::tolower(c); });
        if (vext != ".mp4" && vext != ".gif")
            throw UsageError("--video " + a.video + ": the video must end in .mp4 or .gif");
        if (a.fps < 1 || a.fps > 240) throw UsageError("--fps must be in 1..240");
    }
    if (!a.depth_out.empty()) check_float_output("--depth-out", a.depth_out);
    if (!a.first_hit_out.empty()) check_float_output("--first-hit-out", a.first_hit_out);
    if ((!a.depth_out.empty() || !a.first_hit_out.empty()) && a.orbit_frames > 0)
        throw UsageError("--depth-out and --first-hit-out go with single images, not --orbit-frames");
    Scene scene = a.scene.load("render");
    if (a.depth_channels && ext != ".exr")
        throw UsageError("--depth-channels needs an .exr output (-o ...exr)");
    scene.settings.depth_outputs = !a.depth_out.empty() || !a.first_hit_out.empty() || a.depth_channels;
    if (!a.transforms.empty() && scene.camera.projection != Projection::perspective)
        throw UsageError("--transforms needs a perspective camera (NeRF sets have a field of view)");
    // A turntable's renderer takes the volume over (its frames pay for the
    // bricks; one image would not: docs/performance.md "Bricks").
    const Vec3 center = volume_bounds(scene.volume).center;
    const Renderer renderer = a.orbit_frames > 0 ? scene.take_renderer() : scene.renderer();
    if (a.orbit_frames == 0) {
        Progress progress(!a.quiet);
        const Image image = renderer.render(scene.camera, [&](int d, int t) { progress(d, t); });
        write_image(a.output, image, scene.settings.transparent);
        if (!a.depth_out.empty()) write_image(a.depth_out, gray(image, image.depth));
        if (!a.first_hit_out.empty()) write_image(a.first_hit_out, gray(image, image.first_hit));
        return;
    }
    // A turntable: frame f turned f·360/N degrees about the box centre's vertical axis.
    std::vector<fs::path> files;
    std::vector<Camera> cams;
    std::unique_ptr<VideoWriter> video;
    if (!a.video.empty())
        video = std::make_unique<VideoWriter>(a.video, scene.settings.width, scene.settings.height, a.fps);
    Image image;  // each frame into the last one's
    for (int f = 0; f < a.orbit_frames; ++f) {
        const Camera cam = scene.camera.turned(center, 360.0 * f / a.orbit_frames);
        Progress progress(!a.quiet);
        renderer.render(cam, image, [&](int d, int t) { progress(d, t); });
        files.push_back(frame_path(a.output, f));
        cams.push_back(cam);
        write_image(files.back(), image, scene.settings.transparent);
        if (video) video->add(image);
    }
    if (video) video->finish();
    if (!a.transforms.empty()) write_transforms(a.transforms, scene, files, cams);
}

}  // namespace

void add_render_command(CLI::App& app) {
    auto* cmd = app.add_subcommand("render",
                                   "Render a scene file (or a volume with a transfer function) to an image");
    auto a = std::make_shared<RenderArgs>();
    a->scene.add_to(cmd);
    cmd->add_option("-o,--output", a->output, "Output image: .pfm (linear float), .png (sRGB 8-bit) or .exr")
        ->required();
    cmd->add_flag("-q,--quiet", a->quiet, "No progress indicator");
    cmd->add_option(
        "--depth-out", a->depth_out,
        "Also write the expected termination depth per pixel (world units; .pfm or .exr; inf = none)");
    cmd->add_option(
        "--first-hit-out", a->first_hit_out,
        "Also write the first-hit depth per pixel (first sample with opacity, or the first isosurface)");
    cmd->add_flag("--depth-channels", a->depth_channels,
                  "With an .exr output: add the expected depth (channel Z) and the first-hit depth "
                  "(FirstHit.Z) to the image");
    cmd->add_option(
        "--orbit-frames", a->orbit_frames,
        "Render N frames turning 360/N degrees each about the volume's vertical axis: OUT_000.ext ...");
    cmd->add_option("--video", a->video,
                    "With --orbit-frames: also encode the frames as a video, .mp4 (H.264) or .gif (needs a "
                    "build with FFmpeg's libraries)");
    cmd->add_option("--fps", a->fps, "Frame rate of --video (default 24)");
    cmd->add_option("--transforms", a->transforms,
                    "With --orbit-frames: also write the frames' cameras as a NeRF transforms.json");
    cmd->callback([a] { run_render(*a); });
}

}  // namespace fathom::cli
