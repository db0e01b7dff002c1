// Frame time of the integrators on a synthetic 128³ uint8 volume (Google Benchmark).
// Build with -DFATHOM_BUILD_BENCH=ON; run ./build/bench/fathom_bench.
#include <cmath>

#include <benchmark/benchmark.h>

#include "fathom/preintegration.h"
#include "fathom/render.h"

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

void render(benchmark::State& state, fathom::IntegratorKind kind) {
    static const fathom::Volume vol = make_volume();
    const auto tf = fathom::TransferFunction::preset("ct-soft-tissue", {0.0, 255.0});
    fathom::RenderSettings s;
    s.width = s.height = static_cast<int>(state.range(0));
    s.integrator = kind;
    s.threads = 1;
    const fathom::Renderer r(vol, tf, s);
    const auto b = fathom::volume_bounds(vol);
    const auto cam = fathom::Camera::orbit(30, 20, 3, b.center, b.radius);
    for (auto _ : state) benchmark::DoNotOptimize(r.render(cam));
    state.counters["pixels/s"] = benchmark::Counter(static_cast<double>(s.width) * s.height,
                                                    benchmark::Counter::kIsIterationInvariantRate);
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

}  // namespace

BENCHMARK(table_build)->Arg(1)->Arg(2)->Unit(benchmark::kMillisecond)->UseRealTime();
BENCHMARK_CAPTURE(render, alpha, fathom::IntegratorKind::alpha)->Arg(256)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(render, riemann, fathom::IntegratorKind::riemann)->Arg(256)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(render, reference, fathom::IntegratorKind::reference)
    ->Arg(64)
    ->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
