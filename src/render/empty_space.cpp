#include "render/empty_space.h"

#include <atomic>
#include <limits>
#include <thread>

namespace fathom {
namespace {

struct Range {
    double lo = std::numeric_limits<double>::infinity();
    double hi = -std::numeric_limits<double>::infinity();
    bool nan = false;
};

/// The node range of every macrocell of component 0 of `v`, macrocell
/// slabs (fixed z) spread over threads.
std::vector<Range> macrocell_ranges(const Volume& v, const std::array<std::int64_t, 3>& md, int shift,
                                    int threads) {
    const std::int64_t cells = std::int64_t{1} << shift;
    const auto& n = v.dims();
    const std::int64_t comps = v.components();
    std::vector<Range> out(static_cast<std::size_t>(md[0] * md[1] * md[2]));
    visit_dtype(v.dtype(), [&]<class T>(T*) {
        const T* data = v.data<T>();
        std::atomic<std::int64_t> next{0};
        auto worker = [&] {
            for (std::int64_t mz = next++; mz < md[2]; mz = next++) {
                const std::int64_t z0 = mz * cells, z1 = std::min(z0 + cells, n[2] - 1);
                for (std::int64_t my = 0; my < md[1]; ++my) {
                    const std::int64_t y0 = my * cells, y1 = std::min(y0 + cells, n[1] - 1);
                    for (std::int64_t mx = 0; mx < md[0]; ++mx) {
                        const std::int64_t x0 = mx * cells, x1 = std::min(x0 + cells, n[0] - 1);
                        Range r;
                        for (std::int64_t z = z0; z <= z1; ++z)
                            for (std::int64_t y = y0; y <= y1; ++y) {
                                const T* row = data + (n[0] * (y + n[1] * z)) * comps;
                                for (std::int64_t x = x0; x <= x1; ++x) {
                                    const double s = static_cast<double>(row[x * comps]);
                                    if (s != s) r.nan = true;
                                    r.lo = std::min(r.lo, s);
                                    r.hi = std::max(r.hi, s);
                                }
                            }
                        out[static_cast<std::size_t>(mx + md[0] * (my + md[1] * mz))] = r;
                    }
                }
            }
        };
        const int nt = std::max(1, std::min<int>(threads, static_cast<int>(md[2])));
        std::vector<std::thread> pool;
        for (int i = 1; i < nt; ++i) pool.emplace_back(worker);
        worker();
        for (auto& t : pool) t.join();
    });
    return out;
}

std::array<std::int64_t, 3> macro_dims(const Volume& v, int shift) {
    std::array<std::int64_t, 3> md{};
    for (int a = 0; a < 3; ++a) md[a] = ((v.dims()[a] - 2) >> shift) + 1;  // n − 1 cells, rounded up
    return md;
}

int resolve_threads(int threads) {
    return threads > 0 ? threads : static_cast<int>(std::max(1u, std::thread::hardware_concurrency()));
}

}  // namespace

template <class Empty>
EmptySpace EmptySpace::from_ranges(const Volume& v, int shift, int threads, Empty&& empty) {
    EmptySpace es;
    es.shift_ = shift;
    es.nodes_ = v.dims();
    es.dims_[0] = macro_dims(v, shift);
    const auto ranges = macrocell_ranges(v, es.dims_[0], shift, resolve_threads(threads));
    es.empty_[0].resize(ranges.size());
    for (std::size_t i = 0; i < ranges.size(); ++i) {
        const bool e = !ranges[i].nan && empty(ranges[i].lo, ranges[i].hi);  // NaN nodes: never empty
        es.empty_[0][i] = e ? 1 : 0;
        es.any_ = es.any_ || e;
    }
    es.build_coarse();
    return es;
}

EmptySpace EmptySpace::for_scalar(const Volume& v, const Classifier& tf, Model m, int shift, int threads) {
    if (m != Model::emission_absorption && m != Model::absorption && m != Model::emission) return {};
    return from_ranges(v, shift, threads,
                       [&](double lo, double hi) { return medium_zero_on(tf, m, lo, hi); });
}

EmptySpace EmptySpace::for_density(const Volume& density, int shift, int threads) {
    return from_ranges(density, shift, threads, [](double lo, double hi) { return lo == 0.0 && hi == 0.0; });
}

void EmptySpace::build_coarse() {
    const auto& f = dims_[0];
    auto& c = dims_[1];
    for (int a = 0; a < 3; ++a) c[a] = ((f[a] - 1) >> kCoarse) + 1;
    empty_[1].assign(static_cast<std::size_t>(c[0] * c[1] * c[2]), 1);
    for (std::int64_t z = 0; z < f[2]; ++z)
        for (std::int64_t y = 0; y < f[1]; ++y)
            for (std::int64_t x = 0; x < f[0]; ++x)
                if (!empty_[0][static_cast<std::size_t>(x + f[0] * (y + f[1] * z))])
                    empty_[1][static_cast<std::size_t>((x >> kCoarse) +
                                                       c[0] * ((y >> kCoarse) + c[1] * (z >> kCoarse)))] = 0;
}

double EmptySpace::empty_fraction() const {
    if (empty_[0].empty()) return 0.0;
    std::size_t n = 0;
    for (auto e : empty_[0]) n += e;
    return static_cast<double>(n) / static_cast<double>(empty_[0].size());
}

}  // namespace fathom
