#include <algorithm>
#include <atomic>
#include <cmath>
#include <thread>

#include "fathom/error.h"
#include "fathom/preintegration.h"

#include "integrate/preintegrated.h"

namespace fathom {

PreintegrationTable build_preintegration_table(const Classifier& tf, double v_lo, double v_hi, int size,
                                               double delta, bool self_attenuation, int threads) {
    if (size < 2 || size > 8192) throw Error("pre-integration table", "size must be in 2..8192");
    if (!(v_hi > v_lo) || !std::isfinite(v_lo) || !std::isfinite(v_hi))
        throw Error("pre-integration table", "value range must be finite with hi > lo");
    if (!(delta > 0) || !std::isfinite(delta))
        throw Error("pre-integration table", "segment length must be > 0");
    PreintegrationTable t;
    t.size = size;
    t.v_lo = v_lo;
    t.v_hi = v_hi;
    t.delta = delta;
    t.self_attenuation = self_attenuation;
    const auto n = static_cast<std::size_t>(size) * static_cast<std::size_t>(size);
    t.alpha.resize(n);
    t.color.resize(n * 3);
    std::atomic<int> next{0};
    auto worker = [&] {
        for (int j = next++; j < size; j = next++)
            for (int i = 0; i < size; ++i) {
                const Segment s = preintegrate_scalar<Model::emission_absorption>(tf, t.v(i), t.v(j), delta,
                                                                                  self_attenuation);
                const std::size_t k = static_cast<std::size_t>(i) +
                                      static_cast<std::size_t>(size) * static_cast<std::size_t>(j);
                t.alpha[k] = static_cast<float>(1.0 - s.transmittance);
                for (int c = 0; c < 3; ++c)
                    t.color[k * 3 + static_cast<std::size_t>(c)] = static_cast<float>(s.radiance[c]);
            }
    };
    int nt = threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
    nt = std::min(nt, size);
    std::vector<std::thread> pool;
    for (int i = 1; i < nt; ++i) pool.emplace_back(worker);
    worker();
    for (auto& th : pool) th.join();
    return t;
}

}  // namespace fathom
