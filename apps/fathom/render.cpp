// fathom render: a scene file, or a volume with a transfer function and an
// orbit, to a PFM, PNG or EXR image (SPEC §8). Flags override the scene.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <mutex>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/scene.h"

#include "commands.h"
#include "scene_args.h"

namespace fathom::cli {
namespace {

namespace fs = std::filesystem;

struct RenderArgs {
    SceneArgs scene;
    std::string output;
    bool quiet = false;
};

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
    const Scene scene = a.scene.load("render");
    const Renderer renderer = scene.renderer();
    Progress progress(!a.quiet);
    const Image image = renderer.render(scene.camera, [&](int d, int t) { progress(d, t); });
    write_image(a.output, image, scene.settings.transparent);
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
    cmd->callback([a] { run_render(*a); });
}

}  // namespace fathom::cli
