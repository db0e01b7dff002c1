// Frame time of the integrators on a synthetic 128³ uint8 volume, and the
// roofline: the inner loops alone with their data in L1/L2 (Google Benchmark).
// Build with -DFATHOM_BUILD_BENCH=ON; run ./build/bench/fathom_bench.
#include <cmath>
#include <random>
#include <vector>

#include <benchmark/benchmark.h>

#include "fathom/io.h"
#include "fathom/preintegration.h"
#include "fathom/render.h"

#include "core/parallel.h"
#include "integrate/alpha.h"
#include "integrate/preintegrated.h"
#include "integrate/simd_preint.h"
#include "render/empty_space.h"
#include "render/medium.h"

namespace {

fathom::Volume make_volume() {
    fathom::Volume v({128, 128, 128}, fathom::DType::u8);
    auto* d = v.data<std::uint8_t>();
    for (int k = 0; k < 128; ++k)
        for (int j = 0; j < 128; ++j)
            for (int i = 0; i < 128; ++i) {
                const double r =
                    std::sqrt((i - 64.0) * (i - 64.0) + (j - 64.0) * (j - 64.0) + (k - 64.0) * (k - 64.0));
                d[i + 128 * (j + 128 * k)] =
                    static_cast<std::uint8_t>(std::clamp(255.0 - 4.0 * r, 0.0, 255.0));
            }
    return v;
}

// Frames of the synthetic volume (ct-soft-tissue, one thread) with settings
// `s` at the benchmark's image size.
void time_frames(benchmark::State& state, fathom::RenderSettings s) {
    static const fathom::Volume vol = make_volume();
    const auto tf = fathom::TransferFunction::preset("ct-soft-tissue", {0.0, 255.0});
    s.width = s.height = static_cast<int>(state.range(0));
    s.threads = 1;
    const fathom::Renderer r(vol, tf, s);
    const auto b = fathom::volume_bounds(vol);
    const auto cam = fathom::Camera::orbit(30, 20, 3, b.center, b.radius);
    for (auto _ : state) benchmark::DoNotOptimize(r.render(cam));
    state.counters["pixels/s"] = benchmark::Counter(static_cast<double>(s.width) * s.height,
                                                    benchmark::Counter::kIsIterationInvariantRate);
}

void render(benchmark::State& state, fathom::IntegratorKind kind) {
    fathom::RenderSettings s;
    s.integrator = kind;
    time_frames(state, s);
}

// Two isosurfaces of the same volume, the outer one translucent: rays cross
// it twice and stop at the inner one, so most of the frame refines crossings
// (isosurface.h's bisection) and shades them.
void render_isosurfaces(benchmark::State& state) {
    fathom::RenderSettings s;
    s.model = fathom::Model::isosurface;
    s.isosurfaces = {{100.0, {1.0, 0.6, 0.5}, 0.4}, {200.0, {1, 1, 1}, 1.0}};
    time_frames(state, s);
}

// Exact pre-integration table of a 256-point transfer function (256² entries).
void table_build(benchmark::State& state) {
    fathom::TransferFunction tf;
    tf.alpha_kind = fathom::TransferFunction::Alpha::opacity;
    for (int i = 0; i < 256; ++i) {
        const double v = i;
        tf.alpha_points.push_back({v, 0.5 + 0.5 * std::sin(0.21 * v) * std::sin(0.033 * v)});
        tf.color_points.push_back({v, {0.5 + 0.5 * std::sin(0.1 * v), 0.5, 0.5 + 0.5 * std::cos(0.07 * v)}});
    }
    const fathom::Classifier c(tf, 1.0);
    const int threads = static_cast<int>(state.range(0));
    for (auto _ : state)
        benchmark::DoNotOptimize(fathom::build_preintegration_table(c, 0.0, 255.0, 256, 1.0, true, threads));
}

// --- The roofline: this machine's peak per core for the inner loops. ---

// A 64³ uint8 volume of smooth random values (256 KiB: fits L2).
const fathom::Volume& cache_volume() {
    static const fathom::Volume v = [] {
        fathom::Volume r({64, 64, 64}, fathom::DType::u8);
        auto* d = r.data<std::uint8_t>();
        for (int k = 0; k < 64; ++k)
            for (int j = 0; j < 64; ++j)
                for (int i = 0; i < 64; ++i)
                    d[i + 64 * (j + 64 * k)] = static_cast<std::uint8_t>(
                        127.5 + 127.5 * std::sin(0.3 * i) * std::cos(0.23 * j) * std::sin(0.17 * k + 0.4));
        return r;
    }();
    return v;
}

// Trilinear interpolation alone: 4096 positions (96 KiB) spread over the
// volume, read in order; samples/s per core.
void roofline_trilinear(benchmark::State& state) {
    const fathom::GridSampler<std::uint8_t> g(cache_volume());
    std::vector<fathom::Vec3> pos(4096);
    std::mt19937 rng(1);
    std::uniform_real_distribution<double> u(0.0, 63.0);
    for (auto& p : pos) p = {u(rng), u(rng), u(rng)};
    double acc = 0;
    for (auto _ : state) {
        for (const auto& p : pos) acc += g(p);
        benchmark::DoNotOptimize(acc);
    }
    state.counters["samples/s"] =
        benchmark::Counter(static_cast<double>(pos.size()), benchmark::Counter::kIsIterationInvariantRate);
}

// The SIMD path's trilinear interpolation alone (simd::interpolate_batch,
// 16 samples per call, the best target) along 64 rays through the cached
// volume at step 0.25: the sampling peak the vectorised inner loop can reach.
void roofline_trilinear_simd(benchmark::State& state) {
    const fathom::Volume& v = cache_volume();
    const fathom::simd::BatchSource src{v.bytes(), v.dtype(), 64, 64, 64, nullptr, nullptr};
    std::vector<fathom::simd::RayGrid> rays;
    std::vector<std::int64_t> counts;
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> u(0.0, 63.0);
    std::int64_t samples = 0;
    for (int i = 0; i < 64; ++i) {
        const fathom::Vec3 a{0.0, u(rng), u(rng)}, b{63.0, u(rng), u(rng)};
        const double len = fathom::length(b - a);
        rays.push_back({a, (b - a) * (1.0 / len), 0.0, 0.25, 0.5, 1});
        counts.push_back(static_cast<std::int64_t>(len / 0.25));
        samples += counts.back();
    }
    alignas(64) double out[fathom::simd::kBatch];
    for (auto _ : state)
        for (std::size_t r = 0; r < rays.size(); ++r)
            for (std::int64_t j = 1; j <= counts[r]; j += fathom::simd::kBatch) {
                fathom::simd::interpolate_batch(
                    src, rays[r], j,
                    static_cast<int>(std::min<std::int64_t>(fathom::simd::kBatch, counts[r] - j + 1)), out);
                benchmark::DoNotOptimize(out);
            }
    state.counters["samples/s"] =
        benchmark::Counter(static_cast<double>(samples), benchmark::Counter::kIsIterationInvariantRate);
}

// A whole ray through the cached volume with one integrator's real code
// (sample, classify, segment rule, compositing; no early termination, no
// skipping): the per-sample peak the renderer's inner loop can reach.
template <fathom::IntegratorKind K, bool Simd = false>
void roofline_ray(benchmark::State& state) {
    const fathom::Volume& v = cache_volume();
    const auto tf = fathom::TransferFunction::preset("ct-soft-tissue", {0.0, 255.0});
    const fathom::Classifier c(tf, 1.0);
    const fathom::ScalarMedium<std::uint8_t> med{fathom::GridSampler<std::uint8_t>(v), &c};
    fathom::RenderSettings s;
    s.termination = 0.0;
    s.integrator = K;
    const double h = 0.25;
    std::vector<fathom::RaySpan> spans;
    std::mt19937 rng(2);
    std::uniform_real_distribution<double> u(0.0, 63.0);
    for (int i = 0; i < 64; ++i) {
        const fathom::Vec3 a{0.0, u(rng), u(rng)}, b{63.0, u(rng), u(rng)};
        const fathom::Vec3 d = b - a;
        const double len = fathom::length(d);
        spans.push_back({0.0, len, a, d * (1.0 / len)});
    }
    std::int64_t samples = 0;
    for (const auto& sp : spans) samples += fathom::segment_count(sp.length(), h);
    const fathom::Rgb bg{0, 0, 0};
    const auto fs = fathom::simd::flatten(c.sigma_function()), fc = fathom::simd::flatten(c.color_function());
    fathom::simd::BatchSource batch{v.bytes(), v.dtype(), 64, 64, 64, &fs, &fc};
    batch.shared_knots = fathom::simd::same_knots(fs, fc);
    batch.zero_below = fathom::zero_below(c, fathom::Model::emission_absorption);
    batch.breaks = &c.breakpoints();
    batch.integrals = &c.integrals();
    if (K == fathom::IntegratorKind::alpha) batch.rule = fathom::simd::PointRule::alpha;  // as the Renderer
    const fathom::Accel acc{nullptr, Simd ? &batch : nullptr};
    for (auto _ : state)
        for (const auto& sp : spans) {
            if constexpr (K == fathom::IntegratorKind::alpha)
                benchmark::DoNotOptimize(
                    fathom::integrate_alpha<fathom::Model::emission_absorption>(med, sp, s, h, bg, acc));
            else
                benchmark::DoNotOptimize(fathom::integrate_preintegrated<fathom::Model::emission_absorption>(
                    med, sp, s, h, bg, K == fathom::IntegratorKind::preintegrated, nullptr, acc.simd));
        }
    state.counters["samples/s"] =
        benchmark::Counter(static_cast<double>(samples), benchmark::Counter::kIsIterationInvariantRate);
}

// The bundled chest CT, read once.
const fathom::Volume& chest_ct() {
    static const fathom::Volume v = fathom::read_volume(FATHOM_SOURCE_DIR "/data/lidc2.nrrd");
    return v;
}

// The SIMD pre-integration of segments alone (simd::preintegrate_batch,
// full, emission–absorption): the ends of 256 rays across the bundled chest
// CT at step 0.5, interpolated once, then pre-integrated kBatch segments a
// call under the preset range(0) (0: ct-soft-tissue, 1: ct-bone), those
// with both ends below the medium's zero range skipped as the renderer
// skips them; segments/s per core, skipped ones included.
void preint_segments(benchmark::State& state) {
    const fathom::Volume& vol = chest_ct();
    const auto tf = fathom::TransferFunction::preset(state.range(0) == 0 ? "ct-soft-tissue" : "ct-bone",
                                                     vol.value_range());
    const double h = 0.5 * vol.smallest_spacing();  // the renderer's step 0.5, in world units
    const fathom::Classifier c(tf, vol.smallest_spacing());
    const auto fs = fathom::simd::flatten(c.sigma_function()), fc = fathom::simd::flatten(c.color_function());
    const auto& n = vol.dims();
    fathom::simd::BatchSource src{vol.bytes(), vol.dtype(), n[0], n[1], n[2], &fs, &fc};
    src.shared_knots = fathom::simd::same_knots(fs, fc);
    src.zero_below = fathom::zero_below(c, fathom::Model::emission_absorption);
    src.breaks = &c.breakpoints();
    constexpr int kEnds = fathom::simd::kBatch + 1;
    struct Window {
        alignas(64) double ends[fathom::simd::kBatch + 8];
        std::uint32_t skip;
    };
    std::vector<Window> windows;
    std::mt19937 rng(3);
    std::uniform_real_distribution<double> y(0.0, static_cast<double>(n[1] - 1)),
        z(0.0, static_cast<double>(n[2] - 1));
    for (int i = 0; i < 256; ++i) {
        const fathom::Vec3 a{0.0, y(rng), z(rng)}, b{static_cast<double>(n[0] - 1), y(rng), z(rng)};
        const double len = fathom::length(b - a);
        const fathom::simd::RayGrid ray{a, (b - a) * (1.0 / len), 0.0, 0.5, 0.0, 1};
        const auto ends = static_cast<std::int64_t>(len / 0.5);
        for (std::int64_t j = 0; j + kEnds <= ends; j += kEnds - 1) {
            Window w{};
            std::uint64_t below = 0;
            fathom::simd::interpolate_batch(src, ray, j, kEnds, w.ends, &below);
            w.skip = static_cast<std::uint32_t>(below & (below >> 1) & ((1u << (kEnds - 1)) - 1u));
            windows.push_back(w);
        }
    }
    fathom::simd::SegmentBatch out;
    for (auto _ : state)
        for (const auto& w : windows) {
            fathom::simd::preintegrate_batch(src, fathom::Model::emission_absorption, true, h, w.ends, kEnds,
                                             w.skip, out);
            benchmark::DoNotOptimize(out);
        }
    state.counters["segments/s"] = benchmark::Counter(static_cast<double>(windows.size() * (kEnds - 1)),
                                                      benchmark::Counter::kIsIterationInvariantRate);
}

// A frame's pixel bounds (EmptySpace::pixel_bounds) for the bundled chest
// CT's bone frame (its 2³ macrocells, 34.8 k border boxes; the VTK
// comparison's camera), 512², on range(0) threads.
void pixel_bounds(benchmark::State& state) {
    const fathom::Volume& vol = chest_ct();
    const auto tf = fathom::TransferFunction::preset("ct-bone", vol.value_range());
    const fathom::Classifier c(tf, vol.smallest_spacing());
    const int threads = static_cast<int>(state.range(0));
    const auto es = fathom::EmptySpace::for_scalar(vol, c, fathom::Model::emission_absorption, 1, threads);
    const auto b = fathom::volume_bounds(vol);
    const auto cam = fathom::Camera::orbit(90, 10, 2.6, b.center, b.radius);
    fathom::PixelBounds out;  // kept from frame to frame, as the renderer keeps it
    for (auto _ : state) {
        es.pixel_bounds(out, cam, 512, 512, vol.axes(), vol.origin(), threads);
        benchmark::DoNotOptimize(out.lo.data());
    }
}

// The octants' tables (EmptySpace::ahead and along's three axes) of all
// eight octants for the bundled chest CT's bone frame (its 2³ macrocells),
// built by range(0) threads that ask for the same octant at once, as a
// frame's threads do (the builds are shared); the classification is not
// timed.
void octant_tables(benchmark::State& state) {
    const fathom::Volume& vol = chest_ct();
    const auto tf = fathom::TransferFunction::preset("ct-bone", vol.value_range());
    const fathom::Classifier c(tf, vol.smallest_spacing());
    const int threads = static_cast<int>(state.range(0));
    for (auto _ : state) {
        state.PauseTiming();
        const auto es =
            fathom::EmptySpace::for_scalar(vol, c, fathom::Model::emission_absorption, 1, threads);
        state.ResumeTiming();
        fathom::parallel_blocks(static_cast<std::size_t>(threads), threads,
                                [&](std::size_t, std::size_t, int) {
                                    for (int o = 0; o < 8; ++o) benchmark::DoNotOptimize(es.along(o, 7u));
                                });
    }
}

}  // namespace

BENCHMARK(pixel_bounds)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(octant_tables)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK(roofline_trilinear);
BENCHMARK(roofline_trilinear_simd);
BENCHMARK_TEMPLATE(roofline_ray, fathom::IntegratorKind::alpha)->Name("roofline_ray/alpha");
BENCHMARK_TEMPLATE(roofline_ray, fathom::IntegratorKind::alpha, true)->Name("roofline_ray/alpha-simd");
BENCHMARK_TEMPLATE(roofline_ray, fathom::IntegratorKind::preintegrated)->Name("roofline_ray/preintegrated");
BENCHMARK_TEMPLATE(roofline_ray, fathom::IntegratorKind::preintegrated, true)
    ->Name("roofline_ray/preintegrated-simd");
BENCHMARK_TEMPLATE(roofline_ray, fathom::IntegratorKind::preintegrated_simple)
    ->Name("roofline_ray/preintegrated-simple");
BENCHMARK_TEMPLATE(roofline_ray, fathom::IntegratorKind::preintegrated_simple, true)
    ->Name("roofline_ray/preintegrated-simple-simd");
BENCHMARK(preint_segments)->Arg(0)->Arg(1);
BENCHMARK(table_build)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(render, alpha, fathom::IntegratorKind::alpha)->Arg(256)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(render, riemann, fathom::IntegratorKind::riemann)->Arg(256)->Unit(benchmark::kMillisecond);
BENCHMARK(render_isosurfaces)->Arg(256)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(render, reference, fathom::IntegratorKind::reference)
    ->Arg(64)
    ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
