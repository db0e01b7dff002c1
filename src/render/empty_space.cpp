#include "render/empty_space.h"

#include <algorithm>
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

/// Classifies every macrocell of component 0 of `v` by its node range:
/// 1 where empty(lo, hi) (never with a NaN node), 0 elsewhere; macrocell
/// slabs (fixed z) spread over threads. One byte per macrocell: the ranges
/// are not kept (on the bunny at 4³ cells they would be 36 MB).
template <class Empty>
std::vector<std::uint8_t> classify_macrocells(const Volume& v, const std::array<std::int64_t, 3>& md,
                                              int shift, int threads, const Empty& empty) {
    const std::int64_t cells = std::int64_t{1} << shift;
    const auto& n = v.dims();
    const std::int64_t comps = v.components();
    std::vector<std::uint8_t> out(static_cast<std::size_t>(md[0] * md[1] * md[2]));
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
                        const bool e = !r.nan && empty(r.lo, r.hi);  // NaN nodes: never empty
                        out[static_cast<std::size_t>(mx + md[0] * (my + md[1] * mz))] = e ? 1 : 0;
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
    for (int a = 0; a < 3; ++a) es.node_hi_[a] = static_cast<double>(es.nodes_[a] - 1);
    es.dims_ = macro_dims(v, shift);
    es.empty_ = classify_macrocells(v, es.dims_, shift, resolve_threads(threads), empty);
    es.any_ = std::find(es.empty_.begin(), es.empty_.end(), std::uint8_t{1}) != es.empty_.end();
    es.build_ahead(resolve_threads(threads));
    return es;
}

EmptySpace EmptySpace::for_scalar(const Volume& v, const Classifier& tf, Model m, int shift, int threads) {
    if (m != Model::emission_absorption && m != Model::absorption && m != Model::emission) return {};
    const double e = zero_below(tf, m);
    std::atomic<bool> above{false};  // an empty macrocell reaches E or beyond
    EmptySpace es = from_ranges(v, shift, threads, [&](double lo, double hi) {
        const bool empty = medium_zero_on(tf, m, lo, hi);
        if (empty && !(hi < e)) above.store(true, std::memory_order_relaxed);
        return empty;
    });
    es.joins_empty_ = !above.load();
    return es;
}

EmptySpace EmptySpace::for_density(const Volume& density, int shift, int threads) {
    EmptySpace es =
        from_ranges(density, shift, threads, [](double lo, double hi) { return lo == 0.0 && hi == 0.0; });
    es.joins_empty_ = true;  // σ = 0 at both ends: σ and σ·c are 0 along the segment
    return es;
}

// One pass per octant, from the far corner of that octant back: the box
// reaching r ahead of m is m and the boxes reaching r − 1 ahead of its 7
// neighbours ahead, so D(m) = 1 + min over them, where a neighbour of the
// other kind (empty or not) counts 0; the grid's outside does not stop a
// box, which is clipped.
void EmptySpace::build_ahead(int threads) {
    const std::size_t n = empty_.size();
    ahead_.assign(n * 8, 0);
    const auto& d = dims_;
    auto octant = [&](int o) {
        const std::int64_t s[3] = {(o & 1) != 0 ? -1 : 1, (o & 2) != 0 ? -1 : 1, (o & 4) != 0 ? -1 : 1};
        std::uint8_t* ahead = ahead_.data() + static_cast<std::size_t>(o) * n;  // octant-major
        for (std::int64_t zi = 0; zi < d[2]; ++zi)
            for (std::int64_t yi = 0; yi < d[1]; ++yi)
                for (std::int64_t xi = 0; xi < d[0]; ++xi) {
                    // visit the cells ahead first: against the octant's direction
                    const std::array<std::int64_t, 3> m{s[0] > 0 ? d[0] - 1 - xi : xi,
                                                        s[1] > 0 ? d[1] - 1 - yi : yi,
                                                        s[2] > 0 ? d[2] - 1 - zi : zi};
                    const std::size_t i = index(m);
                    const bool empty = empty_[i] != 0;
                    int best = kMaxDistance;
                    for (int e = 1; e < 8; ++e) {
                        const std::array<std::int64_t, 3> q{m[0] + ((e & 1) != 0 ? s[0] : 0),
                                                            m[1] + ((e & 2) != 0 ? s[1] : 0),
                                                            m[2] + ((e & 4) != 0 ? s[2] : 0)};
                        if (q[0] < 0 || q[1] < 0 || q[2] < 0 || q[0] >= d[0] || q[1] >= d[1] || q[2] >= d[2])
                            continue;
                        const std::size_t k = index(q);  // a neighbour of the other kind stops the box
                        best = std::min(best, (empty_[k] != 0) == empty ? static_cast<int>(ahead[k]) : 0);
                    }
                    ahead[i] = static_cast<std::uint8_t>(std::min(best + 1, kMaxDistance));
                }
    };
    // the octants are independent: spread them over the threads
    std::atomic<int> next{0};
    auto worker = [&] {
        for (int o = next++; o < 8; o = next++) octant(o);
    };
    std::vector<std::thread> pool;
    for (int i = 1; i < std::min(threads, 8); ++i) pool.emplace_back(worker);
    worker();
    for (auto& t : pool) t.join();
}

double EmptySpace::empty_fraction() const {
    if (empty_.empty()) return 0.0;
    std::size_t n = 0;
    for (auto e : empty_) n += e;
    return static_cast<double>(n) / static_cast<double>(empty_.size());
}

}  // namespace fathom
