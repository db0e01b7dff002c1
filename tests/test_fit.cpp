// Reverse rendering end to end: view sets (read and written), the fitter
// reconstructing known grids, exact resumption, and the CLI.
#include <algorithm>
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "fathom/fit.h"
#include "fathom/io.h"
#include "fathom/render.h"
#include "fathom/views.h"

#include "test_util.h"

namespace fathom {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

/// Ground truth: a soft ball of density with a color gradient, 14³ nodes
/// over [0, 13]³.
struct Truth {
    Volume density, color;
};
Truth make_truth() {
    Truth t{Volume({14, 14, 14}, DType::f32), Volume({14, 14, 14}, DType::f32, 3)};
    for (std::int64_t k = 0; k < 14; ++k)
        for (std::int64_t j = 0; j < 14; ++j)
            for (std::int64_t i = 0; i < 14; ++i) {
                const double r = std::hypot(i - 6.5, j - 6.5, k - 6.5);
                t.density.set_value(i, j, k, r < 5.0 ? 0.4 * (1.0 - r / 5.0) : 0.0);
                t.color.set_value(i, j, k, i / 13.0, 0);
                t.color.set_value(i, j, k, j / 13.0, 1);
                t.color.set_value(i, j, k, 0.3, 2);
            }
    return t;
}

/// n views of the truth from directions spread over the sphere (straight
/// alpha, linear, as read_view_set gives them), w×w pixels.
ViewSet render_views(const Truth& t, int n, int w, double turn) {
    RenderSettings s;
    s.width = s.height = w;
    s.integrator = IntegratorKind::alpha;
    s.transparent = true;
    const Renderer r(t.density, t.color, s);
    const Bounds b = volume_bounds(t.density);
    ViewSet set;
    set.camera_angle_x = 30.0 * 3.14159265358979 / 180.0;
    set.bounds = std::array<Vec3, 2>{Vec3{0, 0, 0}, Vec3{13, 13, 13}};
    for (int i = 0; i < n; ++i) {
        const double z = 1.0 - (2.0 * i + 1.0) / n;
        const double az = (i + turn) * 137.5077640500378;
        View v;
        v.camera = Camera::orbit(az, std::asin(z) * 180.0 / 3.14159265358979, 3.0, b.center, b.radius);
        v.image = r.render(v.camera);
        for (std::size_t p = 0; p < v.image.rgba.size(); p += 4) {
            const float a = v.image.rgba[p + 3];
            for (std::size_t c = 0; c < 3; ++c) v.image.rgba[p + c] = a > 0 ? v.image.rgba[p + c] / a : 0.0f;
        }
        set.views.push_back(std::move(v));
    }
    return set;
}

FitOptions small_options() {
    FitOptions o;
    o.bounds = {Vec3{0, 0, 0}, Vec3{13, 13, 13}};
    o.grid = 14;
    o.start_grid = 7;
    o.iterations = 300;
    o.batch = 512;
    o.threads = 1;
    o.background = {1, 1, 1};
    return o;
}

TEST(Fit, ReconstructsKnownGridsFromTheirViews) {
    const Truth t = make_truth();
    const ViewSet train = render_views(t, 24, 24, 0.0), test = render_views(t, 6, 24, 0.5);
    Fitter f(train, small_options());
    const double before = f.psnr(test);
    FitStats last;
    while (!f.done()) last = f.step();
    const double after = f.psnr(test);
    std::printf("[fit] held-out PSNR %.2f dB -> %.2f dB after %d iterations (batch PSNR %.2f dB)\n", before,
                after, f.iteration(), last.psnr);
    EXPECT_EQ(f.iteration(), 300);
    EXPECT_EQ(f.density().dims(), (std::array<std::int64_t, 3>{14, 14, 14}));
    EXPECT_GT(after, before + 10.0);
    EXPECT_GT(after, 30.0);
    // The density came back where the ball is and stayed out of the corners.
    EXPECT_GT(f.density().value(6, 7, 7), 0.15);
    EXPECT_LT(f.density().value(0, 0, 0), 0.05);
}

TEST(Fit, PruningEmptiesBlocksAwayFromTheObjectAndSkipsThem) {
    const Truth t = make_truth();
    const ViewSet train = render_views(t, 24, 24, 0.0), test = render_views(t, 6, 24, 0.5);
    FitOptions o = small_options();
    o.prune = 0.02;
    Fitter f(train, o);
    FitStats last;
    while (!f.done()) last = f.step();
    const double after = f.psnr(test);
    std::printf("[fit] pruned: held-out PSNR %.2f dB, %.0f %% of the macrocells skipped\n", after,
                100.0 * last.empty);
    EXPECT_GT(after, 30.0);
    EXPECT_GT(last.empty, 0.0);
    // Blocks of 4³ cells far from the ball (radius 5 about the center) are exactly 0 ...
    EXPECT_EQ(f.density().value(13, 13, 13), 0.0);
    EXPECT_EQ(f.density().value(13, 1, 2), 0.0);
    // ... the ball is not.
    EXPECT_GT(f.density().value(6, 7, 7), 0.15);
    // Without pruning, nothing is skipped.
    o.prune = 0;
    Fitter g(train, o);
    for (int i = 0; i < 100; ++i) last = g.step();
    EXPECT_EQ(last.empty, 0.0);
}

TEST(Fit, ResumingGivesTheUninterruptedResult) {
    const Truth t = make_truth();
    const ViewSet train = render_views(t, 8, 16, 0.0);
    FitOptions o = small_options();
    o.iterations = 120;  // crosses the 7 → 14 grid change at 60; prunes at 50 and 100
    o.batch = 128;
    o.prune = 0.02;
    Fitter whole(train, o);
    FitStats last;
    while (!whole.done()) last = whole.step();
    EXPECT_GT(last.empty, 0.0);  // the checkpoint below carries pruned blocks
    TempDir d;
    Fitter first(train, o);
    for (int i = 0; i < 105; ++i) (void)first.step();
    first.save_checkpoint(d / "ckpt");
    Fitter second = Fitter::resume(train, o, d / "ckpt");
    EXPECT_EQ(second.iteration(), 105);
    while (!second.done()) (void)second.step();
    ASSERT_EQ(whole.density().dims(), second.density().dims());
    EXPECT_EQ(0,
              std::memcmp(whole.density().bytes(), second.density().bytes(), whole.density().size_bytes()));
    EXPECT_EQ(0, std::memcmp(whole.color().bytes(), second.color().bytes(), whole.color().size_bytes()));
    o.batch = 64;
    test::expect_error([&] { (void)Fitter::resume(train, o, d / "ckpt"); }, "state.json", {"--batch"});
    test::expect_error([&] { (void)Fitter::resume(train, small_options(), d / "nothing"); }, "state.json",
                       {"no checkpoint"});
}

/// A smooth scalar field over [0, 1] (a tilted ramp with a bump), 16³.
Volume scalar_field() {
    Volume v({16, 16, 16}, DType::f32);
    for (std::int64_t k = 0; k < 16; ++k)
        for (std::int64_t j = 0; j < 16; ++j)
            for (std::int64_t i = 0; i < 16; ++i) {
                const double r = std::hypot(i - 7.5, j - 7.5, k - 7.5);
                v.set_value(i, j, k,
                            std::clamp(0.5 * (i + k) / 15.0 + 0.5 * std::exp(-r * r / 20.0), 0.0, 1.0));
            }
    return v;
}

TEST(FitTf, RecoversTransferFunctionValuesFromAFlatStart) {
    const Volume vol = scalar_field();
    TransferFunction truth;
    truth.alpha_kind = TransferFunction::Alpha::opacity;
    truth.alpha_points = {{0.0, 0.02}, {0.35, 0.15}, {0.7, 0.05}, {1.0, 0.3}};
    truth.color_points = {{0.0, {0.9, 0.2, 0.1}}, {0.5, {0.2, 0.8, 0.3}}, {1.0, {0.2, 0.3, 0.95}}};
    // Views rendered with the truth (straight alpha, as a PNG set holds them).
    RenderSettings s;
    s.width = s.height = 24;
    s.transparent = true;
    s.step = 1.0;
    const Renderer r(vol, truth, s);
    const Bounds b = volume_bounds(vol);
    ViewSet views;
    views.camera_angle_x = 0.5;
    for (int i = 0; i < 12; ++i) {
        View v;
        const double z = 1.0 - (2.0 * i + 1.0) / 12;
        v.camera = Camera::orbit(i * 137.5077640500378, std::asin(z) * 180.0 / 3.14159265358979, 3.0,
                                 b.center, b.radius);
        v.image = r.render(v.camera);
        for (std::size_t p = 0; p < v.image.rgba.size(); p += 4)
            for (std::size_t c = 0; c < 3; ++c)
                v.image.rgba[p + c] =
                    v.image.rgba[p + 3] > 0 ? v.image.rgba[p + c] / v.image.rgba[p + 3] : 0.0f;
        views.views.push_back(std::move(v));
    }
    TfFitOptions o;
    o.iterations = 300;
    o.batch = 512;
    o.threads = 1;
    o.lr_alpha = 0.01;
    o.lr_color = 0.02;
    TfFitter f(vol, flattened(truth, 0.05), views, o);
    const double before = f.psnr(views);
    while (!f.done()) (void)f.step();
    const double after = f.psnr(views);
    const TransferFunction& got = f.transfer_function();
    double worst_a = 0, worst_c = 0;
    for (std::size_t i = 0; i < 4; ++i)
        worst_a = std::max(worst_a, std::abs(got.alpha_points[i].second - truth.alpha_points[i].second));
    for (std::size_t i = 0; i < 3; ++i)
        for (int c = 0; c < 3; ++c)
            worst_c =
                std::max(worst_c, std::abs(got.color_points[i].second[c] - truth.color_points[i].second[c]));
    std::printf("[fit-tf] PSNR %.2f -> %.2f dB; largest value error: opacity %.4f, color %.4f\n", before,
                after, worst_a, worst_c);
    EXPECT_GT(after, before + 15.0);
    // The views are exact renders (floats, not 8-bit PNGs): the values come back.
    EXPECT_LT(worst_a, 2e-3);
    EXPECT_LT(worst_c, 5e-3);
    EXPECT_EQ(got.alpha_points[1].first, 0.35);  // positions stay
}

TEST(Fit, OptionsAreChecked) {
    const Truth t = make_truth();
    const ViewSet train = render_views(t, 2, 8, 0.0);
    FitOptions o = small_options();
    o.start_grid = 32;
    test::expect_error([&] { Fitter(train, o); }, "fit options", {"start_grid"});
    o = small_options();
    o.bounds[1].y = -1;
    test::expect_error([&] { Fitter(train, o); }, "fit options", {"bounds"});
    o = small_options();
    o.integrator = IntegratorKind::reference;
    test::expect_error([&] { Fitter(train, o); }, "fit options", {"not differentiable"});
    o = small_options();
    o.level_iterations = {300};  // leaves nothing for the last grid
    test::expect_error([&] { Fitter(train, o); }, "fit options", {"leave iterations"});
    o.level_iterations = {10, 10};  // 7 → 14: one grid before the last
    test::expect_error([&] { Fitter(train, o); }, "fit options", {"only 1 come before"});
    o.level_iterations = {0};
    test::expect_error([&] { Fitter(train, o); }, "fit options", {"≥ 1"});
    o = small_options();
    o.lr_final = 0;
    test::expect_error([&] { Fitter(train, o); }, "fit options", {"lr_final"});
}

// With --lr-final the steps decay over each level: the last step of a level
// moves the grids by about lr_final times what a constant step size moves them.
TEST(Fit, LrFinalDecaysTheStepsOverEachLevel) {
    const Truth t = make_truth();
    const ViewSet train = render_views(t, 4, 12, 0.0);
    auto last_change = [&](double lr_final) {
        FitOptions o = small_options();
        o.iterations = 20;
        o.level_iterations = {10};
        o.batch = 64;
        o.prune = 0;
        o.lr_final = lr_final;
        Fitter f(train, o);
        for (int i = 0; i < 19; ++i) f.step();
        const Volume before = f.density();
        f.step();
        double most = 0;
        const float* a = before.data<float>();
        const float* b = f.density().data<float>();
        for (std::int64_t n = 0; n < before.num_nodes(); ++n)
            most = std::max(most, std::fabs(double(b[n]) - a[n]));
        return most;
    };
    const double constant = last_change(1.0), decayed = last_change(1e-6);
    std::printf("[fit] last step's largest density change: %.3g (constant), %.3g (lr_final 1e-6)\n", constant,
                decayed);
    EXPECT_GT(constant, 1e-4);
    EXPECT_LT(decayed, 1e-6);
}

TEST(Fit, LevelIterationsSetTheSchedule) {
    const Truth t = make_truth();
    const ViewSet train = render_views(t, 2, 8, 0.0);
    FitOptions o = small_options();
    o.start_grid = 4;  // 4 → 8 → 14
    o.iterations = 12;
    o.batch = 16;
    o.level_iterations = {3};  // 3 on 4³, 3 on 8³ (the entry repeats), 6 on 14³
    Fitter f(train, o);
    std::vector<int> grids;
    while (!f.done()) grids.push_back(f.step().grid);
    EXPECT_EQ(grids, (std::vector<int>{4, 4, 4, 8, 8, 8, 14, 14, 14, 14, 14, 14}));
    o.level_iterations = {2, 7};
    Fitter g(train, o);
    grids.clear();
    while (!g.done()) grids.push_back(g.step().grid);
    EXPECT_EQ(grids, (std::vector<int>{4, 4, 8, 8, 8, 8, 8, 8, 8, 14, 14, 14}));
}

TEST(ViewSets, ViewsCommandWritesWhatTheReaderReads) {
    TempDir d;
    const Truth t = make_truth();
    write_nrrd(d / "density.nrrd", t.density);
    write_nrrd(d / "color.nrrd", t.color);
    test::write_file_bytes(d / "scene.json", R"({"format": "fathom-scene/1",
      "volume": {"density": "density.nrrd", "color": "color.nrrd"},
      "camera": {"orbit": {"azimuth": 0, "elevation": 0, "distance": 3}},
      "render": {"width": 20, "height": 16, "integrator": "alpha"}})");
    const auto ok = test::run_cli(
        "views " + (d / "scene.json").string() + " --train 5 --test 2 -q -o " + (d / "set").string(), d);
    ASSERT_EQ(ok.status, 0) << ok.err;
    const ViewSet train = read_view_set(d / "set" / "transforms_train.json");
    const ViewSet test = read_view_set(d / "set" / "transforms_test.json");
    ASSERT_EQ(train.views.size(), 5u);
    ASSERT_EQ(test.views.size(), 2u);
    EXPECT_EQ(train.width(), 20);
    EXPECT_EQ(train.height(), 16);
    ASSERT_TRUE(train.bounds.has_value());
    EXPECT_NEAR((*train.bounds)[1].x, 13.0, 1e-12);
    // Each view is what the renderer gives from its camera (PNG: 8 bits).
    RenderSettings s;
    s.width = 20;
    s.height = 16;
    s.integrator = IntegratorKind::alpha;
    const Renderer ren(t.density, t.color, s);
    for (const View& v : train.views) {
        EXPECT_NEAR(v.camera.fov_y_deg, 30.0, 1e-9);
        const Image img = ren.render(v.camera);
        for (std::size_t p = 0; p < img.rgba.size(); p += 4) {
            ASSERT_NEAR(v.image.rgba[p + 3], img.rgba[p + 3], 1.0 / 255 + 1e-6);
            if (img.rgba[p + 3] > 0.2f) {
                for (std::size_t c = 0; c < 3; ++c)
                    EXPECT_NEAR(v.image.rgba[p + c], img.rgba[p + c] / img.rgba[p + 3], 0.02);
            }
        }
    }
}

TEST(ViewSets, BadSetsAreOneClearError) {
    TempDir d;
    auto set = [&](const std::string& json) {
        test::write_file_bytes(d / "t.json", json);
        return d / "t.json";
    };
    test::expect_error([&] { (void)read_view_set(d / "missing.json"); }, "missing.json", {"cannot open"});
    test::expect_error([&] { (void)read_view_set(set("{ nope")); }, "t.json", {"not valid JSON"});
    test::expect_error([&] { (void)read_view_set(set(R"({"frames": []})")); }, "t.json", {"camera_angle_x"});
    test::expect_error([&] { (void)read_view_set(set(R"({"camera_angle_x": 0.5, "frames": []})")); },
                       "t.json", {"frames"});
    test::expect_error(
        [&] {
            (void)read_view_set(set(R"({"camera_angle_x": 0.5, "frames": [{"file_path": "a",
                "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0]]}]})"));
        },
        "t.json", {"frame 0", "4×4"});
    test::expect_error(
        [&] {
            (void)read_view_set(set(R"({"camera_angle_x": 0.5, "frames": [{"file_path": "a",
                "transform_matrix": [[2,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})"));
        },
        "t.json", {"orthonormal"});
    test::expect_error(
        [&] {
            (void)read_view_set(set(
                R"({"camera_angle_x": 0.5, "fathom_bounds": [[0,0,0],[1,-1,1]], "frames": [{"file_path": "a",
                "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})"));
        },
        "t.json", {"fathom_bounds"});
    test::expect_error(
        [&] {
            (void)read_view_set(set(R"({"camera_angle_x": 0.5, "frames": [{"file_path": "a",
                "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})"));
        },
        "a.png", {});
    Image small(4, 4), big(5, 4);
    write_image(d / "a.png", small, true);
    write_image(d / "b.png", big, true);
    test::expect_error(
        [&] {
            (void)read_view_set(set(R"({"camera_angle_x": 0.5, "frames": [
              {"file_path": "a", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]},
              {"file_path": "b.png", "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})"));
        },
        "b.png", {"differs"});
}

TEST(FitCli, ViewsThenFitThenRender) {
    TempDir d;
    const Truth t = make_truth();
    write_nrrd(d / "density.nrrd", t.density);
    write_nrrd(d / "color.nrrd", t.color);
    test::write_file_bytes(d / "scene.json", R"({"format": "fathom-scene/1",
      "volume": {"density": "density.nrrd", "color": "color.nrrd"},
      "camera": {"orbit": {"azimuth": 0, "elevation": 0, "distance": 3}},
      "render": {"width": 16, "height": 16, "integrator": "alpha"}})");
    ASSERT_EQ(
        test::run_cli(
            "views " + (d / "scene.json").string() + " --train 8 --test 2 -q -o " + (d / "set").string(), d)
            .status,
        0);
    const std::string fit = "fit " + (d / "set" / "transforms_train.json").string() +
                            " --grid 8 --start-grid 4 --iterations 30 --batch 64 --threads 1 -q -o " +
                            (d / "out").string();
    const auto r = test::run_cli(fit, d);
    ASSERT_EQ(r.status, 0) << r.err;
    for (const char* f : {"density.nrrd", "color.nrrd", "scene.json", "log.csv", "checkpoint/state.json"})
        EXPECT_TRUE(fs::exists(d / "out" / f)) << f;
    const std::string log = test::read_file_bytes(d / "out" / "log.csv");
    EXPECT_EQ(std::count(log.begin(), log.end(), '\n'), 31);  // header + 30 iterations
    EXPECT_EQ(log.substr(0, log.find('\n')), "iteration,seconds,grid,loss,batch_psnr,test_psnr,empty");
    EXPECT_NE(log.find("\n30,"), std::string::npos);
    const auto render =
        test::run_cli("render " + (d / "out" / "scene.json").string() + " -o " + (d / "fit.pfm").string(), d);
    ASSERT_EQ(render.status, 0) << render.err;
    const Image img = read_pfm(d / "fit.pfm");
    EXPECT_EQ(img.width, 16);
    // Resuming a finished fit with more iterations continues it.
    std::string fit40 = fit;
    fit40.replace(fit40.find("--iterations 30"), 15, "--iterations 40");
    const auto more = test::run_cli(fit40 + " --resume", d);
    ASSERT_EQ(more.status, 0) << more.err;
    const std::string log2 = test::read_file_bytes(d / "out" / "log.csv");
    EXPECT_NE(log2.find("\n40,"), std::string::npos);
    // Errors: no bounds anywhere (a usage error), a broken set (exit 1).
    test::write_file_bytes(d / "nobounds.json",
                           R"({"camera_angle_x": 0.5, "frames": [{"file_path": "set/train/r_000.png",
                "transform_matrix": [[1,0,0,0],[0,1,0,0],[0,0,1,0],[0,0,0,1]]}]})");
    const auto nb = test::run_cli("fit " + (d / "nobounds.json").string() + " -o " + (d / "o2").string(), d);
    EXPECT_EQ(nb.status, 2);
    EXPECT_NE(nb.err.find("--bounds"), std::string::npos) << nb.err;
    test::write_file_bytes(d / "broken.json", "{");
    const auto br = test::run_cli("fit " + (d / "broken.json").string() + " -o " + (d / "o3").string(), d);
    EXPECT_EQ(br.status, 1);
    EXPECT_NE(br.err.find("broken.json"), std::string::npos) << br.err;
}

}  // namespace
}  // namespace fathom
