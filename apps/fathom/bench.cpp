// fathom bench: frame time of a scene (or a volume with a transfer function)
// over several frames, the camera orbiting so that nothing is reused between
// frames; median, min, pixels/s and segments/s, as text or JSON.
#include <sys/resource.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <fstream>
#include <numeric>
#include <string>
#include <thread>

#include <nlohmann/json.hpp>

#include "fathom/io.h"

#include "commands.h"
#include "scene_args.h"

namespace fathom::cli {
namespace {

struct BenchArgs {
    SceneArgs scene;
    int frames = 5;
    double turn = 10.0;  // degrees of azimuth per frame
    std::string json;
};

/// Peak resident set size of this process so far, in bytes.
double peak_rss_bytes() {
    rusage u{};
    getrusage(RUSAGE_SELF, &u);
    return static_cast<double>(u.ru_maxrss) * 1024.0;  // Linux reports KiB
}

/// The CPU's model name (/proc/cpuinfo), or "unknown".
std::string cpu_name() {
    std::ifstream in("/proc/cpuinfo");
    for (std::string line; std::getline(in, line);)
        if (line.starts_with("model name")) {
            const auto colon = line.find(':');
            if (colon != std::string::npos && colon + 2 <= line.size()) return line.substr(colon + 2);
        }
    return "unknown";
}

double seconds_since(std::chrono::steady_clock::time_point t0) {
    return std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
}

void run_bench(const BenchArgs& a) {
    if (a.frames < 1) throw UsageError("--frames must be at least 1");
    const auto t_load = std::chrono::steady_clock::now();
    Scene sc = a.scene.load("bench");
    const double load_s = seconds_since(t_load);
    // what the report needs of the volume, which the renderer takes over
    const Vec3 center = volume_bounds(sc.volume).center;
    const auto dims = sc.volume.dims();
    const DType dtype = sc.volume.dtype();
    const auto volume_bytes = static_cast<double>(sc.volume.size_bytes());
    const auto t_setup = std::chrono::steady_clock::now();
    const Renderer r = sc.take_renderer();
    const double setup_s = seconds_since(t_setup);
    std::vector<double> times;
    std::uint64_t segments = 0;
    Image img;  // rendered into frame after frame, as a viewer's
    for (int f = 0; f < a.frames; ++f) {
        const Camera cam = sc.camera.turned(center, f * a.turn);
        segments += r.count_segments(cam);
        const auto t0 = std::chrono::steady_clock::now();
        r.render(cam, img);
        times.push_back(seconds_since(t0));
    }
    std::vector<double> sorted = times;
    std::sort(sorted.begin(), sorted.end());
    const double median = sorted[sorted.size() / 2], total = std::accumulate(times.begin(), times.end(), 0.0);
    const double pixels = static_cast<double>(sc.settings.width) * sc.settings.height;
    const double first_image = load_s + setup_s + times.front();
    const int threads = sc.settings.threads > 0
                            ? sc.settings.threads
                            : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    nlohmann::json j{{"scene", a.scene.scene.empty() ? a.scene.volume : a.scene.scene},
                     {"width", sc.settings.width},
                     {"height", sc.settings.height},
                     {"model", to_string(sc.settings.model)},
                     {"integrator", to_string(sc.settings.integrator)},
                     {"step", sc.settings.step},
                     {"threads", threads},
                     {"frames", a.frames},
                     {"preset", a.scene.preset},
                     {"dims", dims},
                     {"dtype", std::string(dtype_name(dtype))},
                     {"skip_empty", sc.settings.skip_empty},
                     {"bricks", r.bricked()},
                     {"packets", r.packets()},
                     {"macrocell_cells", r.macrocell_cells()},
                     {"cpu", cpu_name()},
                     {"hardware_threads", std::thread::hardware_concurrency()},
                     {"load_seconds", load_s},
                     {"setup_seconds", setup_s},
                     {"volume_bytes", volume_bytes},
                     {"peak_rss_bytes", peak_rss_bytes()},
                     {"frame_seconds", times},
                     {"median_seconds", median},
                     {"min_seconds", sorted.front()},
                     {"first_seconds", times.front()},  // builds what frames build on first need
                     {"first_image_seconds", first_image},
                     {"pixels_per_second", pixels / median},
                     {"segments_per_second", static_cast<double>(segments) / total}};
    // The integrator, or the model where it ignores the integrator.
    const Model m = sc.settings.model;
    const bool optical = m == Model::emission_absorption || m == Model::absorption || m == Model::emission;
    const std::string what(optical ? to_string(sc.settings.integrator) : to_string(m));
    std::printf(
        "%s %dx%d %s step %g, %d threads: median %.3f s, min %.3f s (%d frames), %.3g pixels/s, %.3g "
        "segments/s; load %.2f s, setup %.3f s, first frame %.3f s (first image %.2f s), peak RSS %.0f MB\n",
        j["scene"].get<std::string>().c_str(), sc.settings.width, sc.settings.height, what.c_str(),
        sc.settings.step, threads, median, sorted.front(), a.frames, pixels / median,
        static_cast<double>(segments) / total, load_s, setup_s, times.front(), first_image,
        peak_rss_bytes() / 1e6);
    if (!a.json.empty()) write_text_file(a.json, j.dump(2) + "\n");
}

}  // namespace

void add_bench_command(CLI::App& app) {
    auto* cmd =
        app.add_subcommand("bench", "Time the rendering of a scene over several frames (camera orbiting)");
    auto a = std::make_shared<BenchArgs>();
    a->scene.add_to(cmd);
    cmd->add_option("--frames", a->frames, "Frames to time (default 5); the median is reported");
    cmd->add_option("--turn", a->turn, "Degrees the camera orbits between frames (default 10)");
    cmd->add_option("--json", a->json, "Also write the figures as JSON to this file");
    cmd->callback([a] { run_bench(*a); });
}

}  // namespace fathom::cli
