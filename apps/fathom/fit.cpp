// fathom fit: reconstruct density and color grids from a view set
// (docs/reverse-rendering.md).
#include "fathom/fit.h"

#include <unistd.h>

#include <chrono>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <optional>

#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/io.h"

#include "commands.h"
#include "scene_args.h"

namespace fathom::cli {
namespace {

namespace fs = std::filesystem;

struct FitArgs {
    std::string train, test, output, background = "white", bounds, integrator = "alpha";
    FitOptions o;
    int eval_every = 0, checkpoint_every = 200;
    bool resume = false, quiet = false;
};

/// The scene file that renders the result like the first view of the set.
void write_scene(const fs::path& out, const Fitter& f, const ViewSet& set) {
    const RenderSettings s = f.render_settings(set.width(), set.height());
    const auto m = set.views.front().camera.to_matrix();
    nlohmann::json rows = nlohmann::json::array();
    for (int r = 0; r < 4; ++r) rows.push_back({m[4 * r], m[4 * r + 1], m[4 * r + 2], m[4 * r + 3]});
    const Rgb bg = *s.background;
    const nlohmann::json j{
        {"format", "fathom-scene/1"},
        {"volume", {{"density", "density.nrrd"}, {"color", "color.nrrd"}}},
        {"camera", {{"camera_to_world", rows}, {"fov_y", set.views.front().camera.fov_y_deg}}},
        {"render",
         {{"width", s.width},
          {"height", s.height},
          {"integrator", std::string(to_string(s.integrator))},
          {"step", s.step},
          {"background", {bg[0], bg[1], bg[2]}}}}};
    write_text_file(out / "scene.json", j.dump(2) + "\n");
}

void run_fit(FitArgs a) {
    FitOptions& o = a.o;
    o.background = parse_background(a.background);
    o.integrator = parse_integrator(a.integrator, "--integrator");
    const ViewSet train = read_view_set(a.train);
    if (!a.bounds.empty()) {
        const auto v = parse_numbers(a.bounds, "--bounds");
        if (v.size() != 6) throw UsageError("--bounds expects XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX");
        o.bounds = {Vec3{v[0], v[1], v[2]}, Vec3{v[3], v[4], v[5]}};
    } else if (train.bounds) {
        o.bounds = *train.bounds;
    } else {
        throw UsageError(a.train + " has no 'fathom_bounds': give the volume's box with --bounds");
    }
    std::string test_path = a.test;
    if (test_path.empty() && fs::path(a.train).filename() == "transforms_train.json" &&
        fs::exists(fs::path(a.train).parent_path() / "transforms_test.json"))
        test_path = (fs::path(a.train).parent_path() / "transforms_test.json").string();
    std::optional<ViewSet> test;
    if (!test_path.empty()) test = read_view_set(test_path);
    try {
        o.validate();
    } catch (const Error& e) {
        throw UsageError(e.what());
    }
    const fs::path out = a.output;
    fs::create_directories(out);
    const fs::path ckpt = out / "checkpoint";
    Fitter f = a.resume ? Fitter::resume(train, o, ckpt) : Fitter(train, o);
    const bool tty = !a.quiet && isatty(STDERR_FILENO);
    std::ofstream log(out / "log.csv", a.resume ? std::ios::app : std::ios::trunc);
    if (!a.resume) log << "iteration,seconds,grid,loss,batch_psnr,test_psnr,empty\n";
    const auto start = std::chrono::steady_clock::now();
    auto elapsed = [&] {
        return std::chrono::duration<double>(std::chrono::steady_clock::now() - start).count();
    };
    int grid = 0;
    while (!f.done()) {
        const FitStats st = f.step();
        const bool level_end = (st.grid != grid && grid != 0);
        grid = st.grid;
        std::string test_psnr;
        const bool eval =
            test && (f.done() || level_end || (a.eval_every > 0 && st.iteration % a.eval_every == 0));
        if (eval) test_psnr = std::to_string(f.psnr(*test));
        log << st.iteration << ',' << elapsed() << ',' << st.grid << ',' << st.loss << ',' << st.psnr << ','
            << test_psnr << ',' << st.empty << '\n';
        if (tty) {
            const int width = 30, filled = width * st.iteration / o.iterations;
            std::fprintf(stderr, "\r[%s%s] %d/%d grid %d loss %.3g PSNR %.2f dB %.0f rays/s%s%s\033[K",
                         std::string(static_cast<std::size_t>(filled), '#').c_str(),
                         std::string(static_cast<std::size_t>(width - filled), ' ').c_str(), st.iteration,
                         o.iterations, st.grid, st.loss, st.psnr, st.rays_per_second,
                         test_psnr.empty() ? "" : " test ", test_psnr.empty() ? "" : test_psnr.c_str());
        }
        if (a.checkpoint_every > 0 && st.iteration % a.checkpoint_every == 0 && !f.done())
            f.save_checkpoint(ckpt);
    }
    if (tty) std::fputs("\n", stderr);
    write_nrrd(out / "density.nrrd", f.density());
    write_nrrd(out / "color.nrrd", f.color());
    write_scene(out, f, test ? *test : train);
    f.save_checkpoint(ckpt);
    if (!a.quiet) {
        std::fprintf(stderr, "fit: %d iterations in %.1f s", f.iteration(), elapsed());
        if (test) std::fprintf(stderr, ", held-out PSNR %.2f dB", f.psnr(*test));
        std::fprintf(stderr, "; wrote %s\n", (out / "scene.json").string().c_str());
    }
}

}  // namespace

void add_fit_command(CLI::App& app) {
    auto* cmd =
        app.add_subcommand("fit", "Reconstruct density and color grids from a view set (reverse rendering)");
    auto a = std::make_shared<FitArgs>();
    cmd->add_option("TRAIN", a->train, "The training set's transforms.json (SPEC §9)")->required();
    cmd->add_option("-o,--output", a->output,
                    "Output folder: density.nrrd, color.nrrd, scene.json, log.csv, checkpoint/")
        ->required();
    cmd->add_option("--test", a->test,
                    "Held-out views' transforms.json (default: transforms_test.json beside TRAIN, if any)");
    cmd->add_option("--grid", a->o.grid, "Final nodes along the longest side (default 128)");
    cmd->add_option("--start-grid", a->o.start_grid, "First grid; doubles up to --grid (default 32)");
    cmd->add_option("--iterations", a->o.iterations, "Iterations (ray batches) in all (default 2000)");
    cmd->add_option("--level-iterations", a->o.level_iterations,
                    "Iterations on each grid before the last, e.g. 500,1000 (default: equal shares)")
        ->delimiter(',');
    cmd->add_option("--batch", a->o.batch, "Rays per iteration (default 4096)");
    cmd->add_option("--lr-density", a->o.lr_density,
                    "Adam step of the density, optical depth per voxel (0.01)");
    cmd->add_option("--lr-color", a->o.lr_color, "Adam step of the color (0.01)");
    cmd->add_option(
        "--lr-final", a->o.lr_final,
        "Step sizes decay exponentially over each grid to this fraction at its end (1: constant)");
    cmd->add_option("--tv-density", a->o.tv_density, "Total-variation weight of the density (3e-3)");
    cmd->add_option("--tv-color", a->o.tv_color, "Total-variation weight of the color (3e-3)");
    cmd->add_option("--background", a->background,
                    "What transparent pixels show: white, black or R,G,B (white)");
    cmd->add_option("--bounds", a->bounds,
                    "The grids' world box XMIN,YMIN,ZMIN,XMAX,YMAX,ZMAX (default: the set's fathom_bounds)");
    cmd->add_option("--integrator", a->integrator,
                    "riemann, alpha, preintegrated, preintegrated-simple (alpha)");
    cmd->add_option("--step", a->o.step, "Sample step in voxels of the current grid (0.5)");
    cmd->add_option("--seed", a->o.seed, "Random seed of the ray batches (1)");
    cmd->add_option("--threads", a->o.threads, "Threads (0: all cores)");
    cmd->add_option(
        "--prune", a->o.prune,
        "Every 50 iterations, prune 4^3-cell blocks whose density lies below this optical depth per voxel "
        "(1e-2; 0: no pruning)");
    cmd->add_flag("!--no-skip-empty", a->o.skip_empty,
                  "March through the pruned blocks instead of skipping them (same result, slower)");
    cmd->add_option("--eval-every", a->eval_every,
                    "Held-out PSNR every N iterations (default: at each grid change and at the end)");
    cmd->add_option("--checkpoint-every", a->checkpoint_every,
                    "Checkpoint every N iterations (200; 0: only at the end)");
    cmd->add_flag("--resume", a->resume, "Continue from OUT/checkpoint");
    cmd->add_flag("-q,--quiet", a->quiet, "No progress");
    cmd->callback([a] { run_fit(*a); });
}

}  // namespace fathom::cli
