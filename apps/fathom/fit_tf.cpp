// fathom fit-tf: fit a transfer function's control values to a view set of a
// scalar volume (docs/reverse-rendering.md).
#include <unistd.h>

#include <chrono>
#include <cmath>
#include <cstdio>
#include <filesystem>
#include <optional>

#include "fathom/error.h"
#include "fathom/fit.h"
#include "fathom/io.h"

#include "commands.h"
#include "scene_args.h"

namespace fathom::cli {
namespace {

namespace fs = std::filesystem;

struct FitTfArgs {
    std::string views, test, volume, positions, truth, output, background = "white",
                                                               integrator = "preintegrated";
    double start_alpha = -1;
    TfFitOptions o;
    bool quiet = false;
};

/// A TF file, or a preset name (fathom's presets scaled to the volume's range).
TransferFunction tf_arg(const std::string& s, const Volume& v) {
    if (fs::exists(s)) return TransferFunction::from_file(s);
    return TransferFunction::preset(s, v.value_range());
}

void run_fit_tf(FitTfArgs a) {
    a.o.background = parse_background(a.background);
    a.o.integrator = parse_integrator(a.integrator, "--integrator");
    try {
        a.o.validate();
    } catch (const Error& e) {
        throw UsageError(e.what());
    }
    const Volume volume = read_volume(a.volume);
    const ViewSet views = read_view_set(a.views);
    std::optional<ViewSet> test;
    if (!a.test.empty()) test = read_view_set(a.test);
    const TransferFunction like = tf_arg(a.positions, volume);
    const bool opacity = like.alpha_kind == TransferFunction::Alpha::opacity;
    const double start =
        a.start_alpha >= 0 ? a.start_alpha : (opacity ? 0.05 : 0.05 / volume.smallest_spacing());
    TfFitter f(volume, flattened(like, start), views, a.o);
    const bool tty = !a.quiet && isatty(STDERR_FILENO);
    const auto t0 = std::chrono::steady_clock::now();
    FitStats st;
    while (!f.done()) {
        st = f.step();
        if (tty)
            std::fprintf(stderr, "\r%d/%d loss %.3g PSNR %.2f dB %.0f rays/s\033[K", st.iteration,
                         a.o.iterations, st.loss, st.psnr, st.rays_per_second);
    }
    if (tty) std::fputs("\n", stderr);
    write_text_file(a.output, f.transfer_function().to_json());
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("fit-tf: %d iterations in %.1f s, last batch PSNR %.2f dB", st.iteration, secs, st.psnr);
    if (test) std::printf(", held-out PSNR %.2f dB", f.psnr(*test));
    std::printf("\n");
    if (!a.truth.empty()) {  // how far each recovered value is from the known one
        const TransferFunction truth = tf_arg(a.truth, volume);
        const TransferFunction& got = f.transfer_function();
        if (truth.alpha_points.size() != got.alpha_points.size() ||
            truth.color_points.size() != got.color_points.size())
            throw UsageError("--truth must have the control points of --positions");
        double worst_a = 0, worst_c = 0;
        for (std::size_t i = 0; i < got.alpha_points.size(); ++i) {
            const double e = got.alpha_points[i].second - truth.alpha_points[i].second;
            worst_a = std::max(worst_a, std::abs(e));
            std::printf("alpha  v=%-10g truth %-10.4g fitted %-10.4g error %+.4g\n",
                        got.alpha_points[i].first, truth.alpha_points[i].second, got.alpha_points[i].second,
                        e);
        }
        for (std::size_t i = 0; i < got.color_points.size(); ++i) {
            const Rgb& t = truth.color_points[i].second;
            const Rgb& g = got.color_points[i].second;
            double e = 0;
            for (int c = 0; c < 3; ++c) e = std::max(e, std::abs(g[c] - t[c]));
            worst_c = std::max(worst_c, e);
            std::printf("color  v=%-10g truth (%.3f %.3f %.3f) fitted (%.3f %.3f %.3f) max error %.4g\n",
                        got.color_points[i].first, t[0], t[1], t[2], g[0], g[1], g[2], e);
        }
        std::printf("largest error: alpha %.4g, color %.4g\n", worst_a, worst_c);
    }
}

}  // namespace

void add_fit_tf_command(CLI::App& app) {
    auto* cmd = app.add_subcommand(
        "fit-tf", "Fit a transfer function's values (positions fixed) to a view set of a scalar volume");
    auto a = std::make_shared<FitTfArgs>();
    cmd->add_option("VIEWS", a->views, "The view set's transforms.json (SPEC §9)")->required();
    cmd->add_option("--volume", a->volume, "The scalar volume the views show")->required();
    cmd->add_option(
           "--positions", a->positions,
           "A TF file or preset whose control positions (and alpha kind) are kept; the values start flat")
        ->required();
    cmd->add_option("-o,--output", a->output, "The fitted TF (fathom-tf/1 JSON)")->required();
    cmd->add_option("--start-alpha", a->start_alpha,
                    "Every alpha value at the start (default 0.05 opacity, or 0.05 per smallest spacing)");
    cmd->add_option("--truth", a->truth, "A TF with the same points: print the error of every fitted value");
    cmd->add_option("--test", a->test, "Held-out views' transforms.json: print their PSNR");
    cmd->add_option("--iterations", a->o.iterations, "Iterations (ray batches) (300)");
    cmd->add_option("--batch", a->o.batch, "Rays per iteration (4096)");
    cmd->add_option("--lr-alpha", a->o.lr_alpha, "Adam step of the alpha values (0.01)");
    cmd->add_option("--lr-color", a->o.lr_color, "Adam step of the colors (0.02)");
    cmd->add_option("--background", a->background,
                    "What transparent pixels show: white, black or R,G,B (white)");
    cmd->add_option("--integrator", a->integrator, "riemann, alpha, preintegrated, preintegrated-simple");
    cmd->add_option("--step", a->o.step, "Sample step in units of the smallest spacing (1)");
    cmd->add_option("--seed", a->o.seed, "Random seed of the ray batches (1)");
    cmd->add_option("--threads", a->o.threads, "Threads (0: all cores)");
    cmd->add_flag("-q,--quiet", a->quiet, "No progress");
    cmd->callback([a] { run_fit_tf(*a); });
}

}  // namespace fathom::cli
