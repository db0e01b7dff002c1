// Frame time of the integrators on a synthetic 128³ uint8 volume (Google Benchmark).
// Build with -DFATHOM_BUILD_BENCH=ON; run ./build/bench/fathom_bench.
#include <cmath>

#include <benchmark/benchmark.h>

#include "fathom/render.h"

namespace {

fathom::Volume make_volume() {
    fathom::Volume v({128, 128, 128}, fathom::DType::u8);
    auto* d = v.data<std::uint8_t>();
    for (int k = 0; k < 128; ++k)
        for (int j = 0; j < 128; ++j)
            for (int i = 0; i < 128; ++i) {
                const double r = std::sqrt((i - 64.0) * (i - 64.0) + (j - 64.0) * (j - 64.0) + (k - 64.0) * (k - 64.0));
                d[i + 128 * (j + 128 * k)] = static_cast<std::uint8_t>(std::clamp(255.0 - 4.0 * r, 0.0, 255.0));
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

}  // namespace

BENCHMARK_CAPTURE(render, alpha, fathom::IntegratorKind::alpha)->Arg(256)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(render, riemann, fathom::IntegratorKind::riemann)->Arg(256)->Unit(benchmark::kMillisecond);
BENCHMARK_CAPTURE(render, reference, fathom::IntegratorKind::reference)->Arg(64)->Unit(benchmark::kMillisecond);

BENCHMARK_MAIN();
