// fathom render: a scene file, or a volume with a transfer function and an
// orbit, to a PFM, PNG or EXR image (SPEC §8). Flags override the scene.
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <chrono>
#include <cstdio>
#include <filesystem>
#include <mutex>
#include <sstream>

#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/scene.h"

#include "commands.h"

namespace fathom::cli {
namespace {

namespace fs = std::filesystem;

struct RenderArgs {
    std::string scene, output, volume, tf, preset, orbit, background;
    int width = 0, height = 0, threads = 0;
    std::string model, integrator, order, sample_point, step_unit;
    double step = 0, termination = 0;
    bool quiet = false;
    CLI::Option *o_width{}, *o_height{}, *o_step{}, *o_termination{}, *o_threads{};
};

std::vector<double> parse_numbers(const std::string& text, const std::string& flag) {
    std::vector<double> out;
    std::stringstream ss(text);
    std::string item;
    while (std::getline(ss, item, ',')) {
        try {
            std::size_t used = 0;
            out.push_back(std::stod(item, &used));
            if (used != item.size()) throw std::invalid_argument(item);
        } catch (const std::exception&) {
            throw UsageError(flag + ": '" + text + "' is not a comma-separated list of numbers");
        }
    }
    return out;
}

// The no-scene form becomes a scene in memory, so both forms share one parser.
std::string scene_from_flags(const RenderArgs& a) {
    using nlohmann::json;
    if (a.tf.empty() == a.preset.empty()) throw UsageError("--volume needs exactly one of --tf and --preset");
    json tf = a.tf.empty() ? json{{"preset", a.preset}} : json{{"path", fs::absolute(a.tf).string()}};
    json orbit = {{"azimuth", 45.0}, {"elevation", 30.0}};
    if (!a.orbit.empty()) {
        const auto v = parse_numbers(a.orbit, "--orbit");
        if (v.size() < 2 || v.size() > 3) throw UsageError("--orbit expects AZ,EL[,DIST]");
        orbit = {{"azimuth", v[0]}, {"elevation", v[1]}};
        if (v.size() == 3) orbit["distance"] = v[2];
    }
    return json{{"format", "fathom-scene/1"},
                {"volume", {{"path", fs::absolute(a.volume).string()}}},
                {"transfer_function", tf},
                {"camera", {{"orbit", orbit}}}}
        .dump();
}

void apply_overrides(RenderSettings& s, const RenderArgs& a) {
    const std::string flag = "command line";
    if (a.o_width->count()) s.width = a.width;
    if (a.o_height->count()) s.height = a.height;
    if (!a.model.empty()) s.model = parse_model(a.model, flag);
    if (!a.integrator.empty()) s.integrator = parse_integrator(a.integrator, flag);
    if (!a.order.empty()) s.order = parse_order(a.order, flag);
    if (!a.sample_point.empty()) s.sample_point = parse_sample_point(a.sample_point, flag);
    if (!a.step_unit.empty()) s.step_world = a.step_unit == "world";
    if (a.o_step->count()) s.step = a.step;
    if (a.o_termination->count()) s.termination = a.termination;
    if (a.o_threads->count()) s.threads = a.threads;
    if (!a.background.empty()) {
        if (a.background == "transparent") {
            s.transparent = true;
        } else {
            const auto v = parse_numbers(a.background, "--background");
            if (v.size() != 3) throw UsageError("--background expects R,G,B or 'transparent'");
            s.background = Rgb{v[0], v[1], v[2]};
            s.transparent = false;
        }
    }
    s.validate();
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
    if (a.scene.empty() == a.volume.empty())
        throw UsageError("render needs either a SCENE file or --volume (not both)");
    if (a.scene.empty() == false && (!a.tf.empty() || !a.preset.empty() || !a.orbit.empty()))
        throw UsageError("--tf, --preset and --orbit go with --volume, not with a scene file");
    std::string ext = fs::path(a.output).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext != ".pfm" && ext != ".png" && ext != ".exr")
        throw UsageError("-o " + a.output + ": the output must end in .pfm, .png or .exr");

    Scene scene = a.scene.empty() ? parse_scene(scene_from_flags(a), fs::current_path(), a.volume)
                                  : load_scene(a.scene);
    try {
        apply_overrides(scene.settings, a);
    } catch (const Error& e) {
        throw UsageError(e.reason());
    }
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
    cmd->add_option("scene", a->scene, "Scene file (fathom-scene/1 JSON)");
    cmd->add_option("-o,--output", a->output, "Output image: .pfm (linear float), .png (sRGB 8-bit) or .exr")
        ->required();
    cmd->add_option("--volume", a->volume, "Volume file (no-scene form)");
    cmd->add_option("--tf", a->tf, "Transfer function file (fathom-tf/1 JSON), with --volume");
    cmd->add_option(
        "--preset", a->preset,
        "Transfer function preset, with --volume: ct-bone, ct-skin, ct-soft-tissue, mr-default, grayscale");
    cmd->add_option(
        "--orbit", a->orbit,
        "Orbit camera AZ,EL[,DIST] in degrees (distance in half box diagonals, default 3), with --volume");
    a->o_width = cmd->add_option("--width", a->width, "Image width in pixels (default 512)");
    a->o_height = cmd->add_option("--height", a->height, "Image height in pixels (default 512)");
    cmd->add_option("--model", a->model, "emission-absorption (default), absorption, emission or mip");
    cmd->add_option("--integrator", a->integrator, "alpha (default), riemann or reference");
    a->o_step =
        cmd->add_option("--step", a->step, "Step: in voxels (smallest spacing) by default, see --step-unit");
    cmd->add_option("--step-unit", a->step_unit, "voxel (default) or world")
        ->check(CLI::IsMember({"voxel", "world"}));
    cmd->add_option("--sample-point", a->sample_point, "near (default) or mid");
    cmd->add_option("--order", a->order, "front-to-back (default) or back-to-front");
    a->o_termination = cmd->add_option("--termination", a->termination,
                                       "Early-termination threshold on T (default 0.001; 0 never stops)");
    cmd->add_option("--background", a->background, "R,G,B or 'transparent'");
    a->o_threads = cmd->add_option("--threads", a->threads, "Threads (default: all cores)")
                       ->check(CLI::NonNegativeNumber);
    cmd->add_flag("-q,--quiet", a->quiet, "No progress indicator");
    cmd->callback([a] { run_render(*a); });
}

}  // namespace fathom::cli
