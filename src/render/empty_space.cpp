#include "render/empty_space.h"

#include <sys/mman.h>
#include <unistd.h>

#include <algorithm>
#include <atomic>
#include <bit>
#include <cmath>
#include <limits>
#include <new>
#include <numbers>
#include <thread>
#include <type_traits>
#include <vector>

#include "core/parallel.h"
#include "render/simd_bounds.h"

namespace fathom {
namespace {

/// Calls store(i, lo, hi, nan) for every macrocell i (index order) of
/// component 0 of `v`, with the range [lo, hi] of its nodes and whether
/// one of them is NaN (left out of the range); macrocell rows spread over
/// threads. For each macrocell row, the node rows it spans are reduced
/// column by column, in the sample type (conversion to double keeps order,
/// so the range is the same), and then each macrocell's window of columns.
template <class Store>
void reduce_macrocells(const Volume& v, const std::array<std::int64_t, 3>& md, int shift, int threads,
                       const Store& store) {
    const std::int64_t cells = std::int64_t{1} << shift;
    const auto& n = v.dims();
    const std::int64_t comps = v.components();
    visit_dtype(v.dtype(), [&]<class T>(T*) {
        constexpr bool kFloat = std::is_floating_point_v<T>;
        constexpr T kLo = kFloat ? std::numeric_limits<T>::infinity() : std::numeric_limits<T>::max();
        constexpr T kHi = kFloat ? -std::numeric_limits<T>::infinity() : std::numeric_limits<T>::lowest();
        const T* data = v.data<T>();
        const auto columns = static_cast<std::size_t>(n[0]);
        parallel_items(md[1] * md[2], threads, [&](std::int64_t r) {  // macrocell row (my, mz)
            const std::int64_t my = r % md[1], mz = r / md[1];
            // per node column: the range of the macrocell row's nodes there,
            // and whether one is NaN (left out of the range)
            std::vector<T> lo(columns, kLo), hi(columns, kHi);
            std::vector<std::uint8_t> nan(kFloat ? columns : 0);
            auto reduce = [&]<std::int64_t kStride>(const T* row, std::int64_t stride) {
                const std::int64_t step = kStride > 0 ? kStride : stride;
                T* l = lo.data();  // local pointers: no reloads in the loop
                T* h = hi.data();
                std::uint8_t* q = nan.data();
                for (std::size_t x = 0; x < columns; ++x) {
                    const T s = row[static_cast<std::int64_t>(x) * step];
                    if constexpr (kFloat) q[x] |= static_cast<std::uint8_t>(s != s);
                    l[x] = std::min(l[x], s);  // a NaN s is never taken
                    h[x] = std::max(h[x], s);
                }
            };
            // macrocell m holds nodes m·cells … min(m·cells + cells, n − 1)
            const std::int64_t y0 = my * cells, y1 = std::min(y0 + cells, n[1] - 1);
            const std::int64_t z0 = mz * cells, z1 = std::min(z0 + cells, n[2] - 1);
            for (std::int64_t z = z0; z <= z1; ++z)
                for (std::int64_t y = y0; y <= y1; ++y) {
                    const T* row = data + (n[0] * (y + n[1] * z)) * comps;
                    if (comps == 1)
                        reduce.template operator()<1>(row, 1);
                    else
                        reduce.template operator()<0>(row, comps);
                }
            for (std::int64_t mx = 0; mx < md[0]; ++mx) {
                const std::int64_t x0 = mx * cells, x1 = std::min(x0 + cells, n[0] - 1);
                T a = kLo, b = kHi;
                bool has_nan = false;
                for (std::int64_t x = x0; x <= x1; ++x) {
                    const auto c = static_cast<std::size_t>(x);
                    a = std::min(a, lo[c]);
                    b = std::max(b, hi[c]);
                    if constexpr (kFloat) has_nan |= nan[c] != 0;
                }
                store(static_cast<std::size_t>(mx + md[0] * r), static_cast<double>(a),
                      static_cast<double>(b), has_nan);
            }
        });
    });
}

/// Classifies every macrocell by its node range: 1 where empty(lo, hi)
/// (never with a NaN node), 0 elsewhere. One byte per macrocell: the
/// ranges are not kept (on the bunny at 4³ cells they would be 36 MB).
template <class Empty>
std::vector<std::uint8_t> classify_macrocells(const Volume& v, const std::array<std::int64_t, 3>& md,
                                              int shift, int threads, const Empty& empty) {
    std::vector<std::uint8_t> out(static_cast<std::size_t>(md[0] * md[1] * md[2]));
    reduce_macrocells(v, md, shift, threads, [&](std::size_t i, double lo, double hi, bool nan) {
        out[i] = !nan && empty(lo, hi) ? 1 : 0;
    });
    return out;
}

}  // namespace

std::array<std::int64_t, 3> MacrocellLattice::dims_of(const std::array<std::int64_t, 3>& nodes, int shift) {
    std::array<std::int64_t, 3> md{};
    for (int a = 0; a < 3; ++a) md[a] = ((nodes[a] - 2) >> shift) + 1;  // n − 1 cells, rounded up
    return md;
}

MacrocellLattice::MacrocellLattice(const std::array<std::int64_t, 3>& nodes, int shift)
    : shift_(shift), nodes_(nodes), dims_(dims_of(nodes, shift)) {
    for (int a = 0; a < 3; ++a) node_hi_[a] = static_cast<double>(nodes_[a] - 1);
}

namespace {

/// An integer below 2^52 in magnitude: its last significand bit is 0.
bool even_integer(double x) {
    return std::abs(x) < 0x1p52 && x == std::floor(x);
}

/// x as a float, rounded down or up.
float down(double x) {
    const auto f = static_cast<float>(x);
    return static_cast<double>(f) <= x ? f : std::nextafter(f, -INFINITY);
}
float up(double x) {
    const auto f = static_cast<float>(x);
    return static_cast<double>(f) >= x ? f : std::nextafter(f, INFINITY);
}

/// The range [lo, hi] of a macrocell's nodes (nan: one is NaN), widened to
/// hold every trilinear sample computed from them (MacrocellRanges).
std::array<double, 2> sample_range(double lo, double hi, bool nan) {
    const double margin = 0x1p-40 * std::max(std::abs(lo), std::abs(hi));
    if (nan || !std::isfinite(margin)) return {-INFINITY, INFINITY};  // a NaN or an infinite node: no bound
    // Where the nodes are ≥ 0, each lerp a + f·(b − a) stays ≥ 0 (b − a
    // rounds to no less than −a) and ≤ hi if hi is an integer (a + (b − a)
    // exceeds hi by half an ulp of hi at most, a tie that rounds to the
    // even hi); the same mirrored where the nodes are ≤ 0. Elsewhere
    // rounding can leave the nodes' range: nodes 1500, 1501 and −1024
    // give −1024 − 2^−42 at fx = 3·2^−42, fy = 1 (MacrocellRanges test).
    const bool exact_lo = lo == 0.0 || (hi <= 0.0 && even_integer(lo));
    const bool exact_hi = hi == 0.0 || (lo >= 0.0 && even_integer(hi));
    return {exact_lo ? lo : lo - margin, exact_hi ? hi : hi + margin};
}

}  // namespace

MacrocellRanges::MacrocellRanges(const Volume& v, int shift, int threads) : MacrocellLattice(v, shift) {
    range_.resize(static_cast<std::size_t>(2 * dims_[0] * dims_[1] * dims_[2]));
    std::atomic<double> lowest_node{INFINITY};  // (the macrocells' threads lower it)
    reduce_macrocells(v, dims_, shift, threads, [&](std::size_t i, double lo, double hi, bool nan) {
        const auto r = sample_range(lo, hi, nan);
        range_[2 * i] = down(r[0]);
        range_[2 * i + 1] = up(r[1]);
        for (double cur = lowest_node.load(std::memory_order_relaxed); std::isfinite(lo) && lo < cur;)
            if (lowest_node.compare_exchange_weak(cur, lo, std::memory_order_relaxed)) break;
    });
    lowest_node_ = lowest_node.load();
    for (std::size_t i = 0; i < range_.size(); i += 2) {
        lowest_ = std::min(lowest_, static_cast<double>(range_[i]));
        highest_ = std::max(highest_, static_cast<double>(range_[i + 1]));
    }
}

MacrocellRanges MacrocellRanges::coarser(int levels) const {
    MacrocellRanges c;
    static_cast<MacrocellLattice&>(c) = MacrocellLattice(nodes_, shift_ + levels);
    const auto& cd = c.dims_;
    c.range_.resize(static_cast<std::size_t>(2 * cd[0] * cd[1] * cd[2]));
    for (std::size_t i = 0; i < c.range_.size(); i += 2) {
        c.range_[i] = INFINITY;
        c.range_[i + 1] = -INFINITY;
    }
    for (std::int64_t z = 0; z < dims_[2]; ++z)
        for (std::int64_t y = 0; y < dims_[1]; ++y)
            for (std::int64_t x = 0; x < dims_[0]; ++x) {
                const std::size_t f = 2 * index({x, y, z}),
                                  k = 2 * c.index({x >> levels, y >> levels, z >> levels});
                c.range_[k] = std::min(c.range_[k], range_[f]);
                c.range_[k + 1] = std::max(c.range_[k + 1], range_[f + 1]);
            }
    c.lowest_ = lowest_;
    c.highest_ = highest_;
    c.lowest_node_ = lowest_node_;
    return c;
}

template <class Empty>
EmptySpace EmptySpace::from_ranges(const Volume& v, int shift, int threads, Empty&& empty) {
    EmptySpace es;
    static_cast<MacrocellLattice&>(es) = MacrocellLattice(v, shift);
    es.empty_ = classify_macrocells(v, es.dims_, shift, threads, empty);
    es.any_ = std::find(es.empty_.begin(), es.empty_.end(), std::uint8_t{1}) != es.empty_.end();
    es.find_border();
    return es;
}

std::vector<std::uint8_t> EmptySpace::groups_empty(const MacrocellLattice& groups) const {
    std::vector<std::uint8_t> out(
        static_cast<std::size_t>(groups.dims()[0] * groups.dims()[1] * groups.dims()[2]), 1);
    for (std::int64_t z = 0; z < dims_[2]; ++z)
        for (std::int64_t y = 0; y < dims_[1]; ++y)
            for (std::int64_t x = 0; x < dims_[0]; ++x)
                if (empty_[index({x, y, z})] == 0) out[groups.index({x / 2, y / 2, z / 2})] = 0;
    return out;
}

EmptySpace EmptySpace::coarser() const {
    EmptySpace c;
    static_cast<MacrocellLattice&>(c) = MacrocellLattice(nodes_, shift_ + 1);
    c.empty_ = groups_empty(c);
    c.any_ = std::find(c.empty_.begin(), c.empty_.end(), std::uint8_t{1}) != c.empty_.end();
    c.joins_empty_ = joins_empty_;
    c.find_border();
    return c;
}

void EmptySpace::find_border() {
    const auto& d = dims_;
    border_.clear();
    if (!any_) return;
    for (std::int64_t z = 0; z < d[2]; ++z)
        for (std::int64_t y = 0; y < d[1]; ++y)
            for (std::int64_t x = 0; x < d[0]; ++x) {
                const std::array<std::int64_t, 3> m{x, y, z};
                const std::size_t i = index(m);
                if (empty_[i] != 0) continue;
                bool border = false;
                for (int a = 0; a < 3 && !border; ++a)
                    for (int s = -1; s <= 1 && !border; s += 2) {
                        auto q = m;
                        q[a] += s;
                        border = q[a] < 0 || q[a] >= d[a] || empty_[index(q)] != 0;
                    }
                if (border) border_.push_back(static_cast<std::uint32_t>(i));
            }
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

EmptySpace EmptySpace::for_isosurfaces(const Volume& v, const std::vector<double>& isos, int shift,
                                       int threads) {
    return from_ranges(v, shift, threads, [&](double lo, double hi) {
        const auto r = sample_range(lo, hi, false);
        return std::all_of(isos.begin(), isos.end(), [&](double iso) { return r[1] < iso || r[0] >= iso; });
    });
}

EmptySpace EmptySpace::for_zeros(const Volume& v, int shift, int threads) {
    EmptySpace es =
        from_ranges(v, shift, threads, [](double lo, double hi) { return lo == 0.0 && hi == 0.0; });
    es.joins_empty_ = true;  // σ = 0 at both ends: σ and σ·c are 0 along the segment
    return es;
}

EmptySpace EmptySpace::for_value(const Volume& v, double value, int shift, int threads) {
    if (value == 0.0) return for_zeros(v, shift, threads);
    return from_ranges(v, shift, threads,
                       [value](double lo, double hi) { return lo == value && hi == value; });
}

EmptySpace EmptySpace::none(const Volume& v, int shift) {
    EmptySpace es;
    static_cast<MacrocellLattice&>(es) = MacrocellLattice(v, shift);
    es.empty_.assign(static_cast<std::size_t>(es.dims_[0] * es.dims_[1] * es.dims_[2]), 0);
    es.joins_empty_ = true;
    return es;
}

void detail::Unmap::operator()(std::uint8_t* p) const noexcept {
    if (p != nullptr) munmap(p, bytes);
}

void detail::populate(std::uint8_t* p, std::size_t bytes) {
#ifdef MADV_POPULATE_WRITE
    static const auto page = static_cast<std::uintptr_t>(sysconf(_SC_PAGESIZE));
    const auto begin = reinterpret_cast<std::uintptr_t>(p) & ~(page - 1),
               end = (reinterpret_cast<std::uintptr_t>(p) + bytes + page - 1) & ~(page - 1);
    // an older kernel refuses (EINVAL): the pages then come with their first writes
    static_cast<void>(madvise(reinterpret_cast<void*>(begin), end - begin, MADV_POPULATE_WRITE));
#else
    static_cast<void>(p);
    static_cast<void>(bytes);
#endif
}

detail::Pages detail::map_pages(std::size_t bytes) {
    bytes = std::max<std::size_t>(bytes, 1);
    void* p = mmap(nullptr, bytes, PROT_READ | PROT_WRITE, MAP_PRIVATE | MAP_ANONYMOUS, -1, 0);
    if (p == MAP_FAILED) throw std::bad_alloc();
    return Pages(static_cast<std::uint8_t*>(p), Unmap{bytes});
}

EmptySpace::Use::Use(const EmptySpace& es, bool releases) : oc_(es.ahead_) {
    if (!oc_) return;
    const std::lock_guard lock(oc_->uses_mutex);
    if (releases && oc_->uses == 0)  // no one holds a table's address
        for (Octants::Table& t : oc_->table) {
            if (!t.read.load(std::memory_order_relaxed)) {
                t.ahead.store(nullptr, std::memory_order_relaxed);
                t.along_axes.store(0, std::memory_order_relaxed);
                t.ahead_pages.reset();
                t.along_pages.reset();
            }
            t.read.store(false, std::memory_order_relaxed);
        }
    ++oc_->uses;
}

EmptySpace::Use::~Use() {
    if (!oc_) return;
    const std::lock_guard lock(oc_->uses_mutex);
    --oc_->uses;
}

std::size_t EmptySpace::table_bytes() const {
    std::size_t bytes = 0;
    for (const Octants::Table& t : ahead_->table) {
        if (t.ahead.load(std::memory_order_acquire) != nullptr) bytes += empty_.size();
        bytes += static_cast<std::size_t>(std::popcount(t.along_axes.load(std::memory_order_acquire))) *
                 empty_.size();
    }
    return bytes;
}

// Whoever needs a table while it is being built helps: the build's units
// (planes of macrocells) are handed out by a counter, and the thread that
// finishes the last one publishes the table. The threads of a frame reach
// a new octant's tables at about the same moment (its first tiles), so
// without this one of them waited for the other's whole build.
struct detail::SharedBuild {
    std::int64_t units = 0;
    unsigned axes = 0;  // along(): the axes built, unit u = (k-th of them, plane)
    std::atomic<std::int64_t> next{0}, finished{0};
    std::unique_ptr<std::atomic<std::int64_t>[]> rows;  // ahead(): rows done per plane

    /// f(u) for units until none is left; true for the thread that
    /// finished the last one.
    template <class F>
    bool work(F&& f) {
        bool last = false;
        for (std::int64_t u = next++; u < units; u = next++) {
            f(u);
            last = finished.fetch_add(1, std::memory_order_acq_rel) + 1 == units;
        }
        return last;
    }
};

const std::uint8_t* EmptySpace::ahead(int o) const {
    Octants::Table& t = ahead_->table[static_cast<std::size_t>(o)];
    if (!t.read.load(std::memory_order_relaxed)) t.read.store(true, std::memory_order_relaxed);
    if (const std::uint8_t* p = t.ahead.load(std::memory_order_acquire)) return p;
    std::shared_ptr<detail::SharedBuild> job;
    std::uint8_t* out = nullptr;
    {
        const std::lock_guard lock(t.build);
        if (const std::uint8_t* p = t.ahead.load(std::memory_order_relaxed)) return p;
        if (!t.ahead_job) {
            t.ahead_pages = detail::map_pages(empty_.size());
            auto j = std::make_shared<detail::SharedBuild>();
            j->units = dims_[2];
            j->rows = std::make_unique<std::atomic<std::int64_t>[]>(static_cast<std::size_t>(j->units));
            t.ahead_job = std::move(j);
        }
        job = t.ahead_job;
        out = t.ahead_pages.get();
    }
    // the one allocation before any plane is taken: nothing inside a
    // build throws, so no thread waits for a plane that never comes
    std::vector<std::uint8_t> best(static_cast<std::size_t>(dims_[0]));
    if (job->work([&](std::int64_t zi) { build_ahead(o, out, zi, *job, best.data()); })) {
        const std::lock_guard lock(t.build);
        t.ahead.store(out, std::memory_order_release);
        t.ahead.notify_all();
        t.ahead_job.reset();
    } else {
        while (t.ahead.load(std::memory_order_acquire) == nullptr)
            t.ahead.wait(nullptr, std::memory_order_acquire);
    }
    return out;
}

const std::uint8_t* EmptySpace::along(int o, unsigned axes) const {
    static_cast<void>(ahead(o));  // built (build_along reads it) and marked read
    Octants::Table& t = ahead_->table[static_cast<std::size_t>(o)];
    const std::int64_t n = static_cast<std::int64_t>(empty_.size()), planes = dims_[2];
    for (;;) {  // until a build covers every axis asked for
        const unsigned built = t.along_axes.load(std::memory_order_acquire);
        if (built != 0 && (built & axes) == axes) return t.along_pages.get();
        std::shared_ptr<detail::SharedBuild> job;
        std::uint8_t* pages = nullptr;
        {
            const std::lock_guard lock(t.build);
            // not written where no axis is built: only the axes built are resident
            if (!t.along_pages) t.along_pages = detail::map_pages(3 * static_cast<std::size_t>(n));
            pages = t.along_pages.get();
            const unsigned now = t.along_axes.load(std::memory_order_relaxed);
            if ((now & axes) == axes) return pages;
            if (!t.along_job) {
                auto j = std::make_shared<detail::SharedBuild>();
                j->axes = axes & ~now;
                j->units = std::popcount(j->axes) * planes;
                t.along_job = std::move(j);
            }
            job = t.along_job;
        }
        if (job->work([&](std::int64_t u) {
                unsigned rest = job->axes;  // the (u / planes)-th axis of the build
                for (std::int64_t k = u / planes; k > 0; --k) rest &= rest - 1;
                const int a = std::countr_zero(rest);
                build_along(o, a, pages + a * n, u % planes);
            })) {
            const std::lock_guard lock(t.build);
            t.along_axes.fetch_or(job->axes, std::memory_order_release);
            t.along_axes.notify_all();
            t.along_job.reset();
        } else {
            unsigned v = 0;
            while (((v = t.along_axes.load(std::memory_order_acquire)) & job->axes) != job->axes)
                t.along_axes.wait(v, std::memory_order_acquire);
        }
    }
}

void EmptySpace::build_along(int o, int a, std::uint8_t* row, std::int64_t z) const {
    // published before any along() build starts
    const std::uint8_t* dist =
        ahead_->table[static_cast<std::size_t>(o)].ahead.load(std::memory_order_acquire);
    const std::uint8_t* kind = empty_.data();  // 0 or 1: compared as bytes
    const auto& d = dims_;
    const std::int64_t s = (o >> a & 1) != 0 ? -1 : 1;
    const std::int64_t stride = a == 0 ? 1 : a == 1 ? d[0] : d[0] * d[1];
    const auto inside = [&](std::int64_t at) {
        return static_cast<std::uint64_t>(at) < static_cast<std::uint64_t>(d[a]);
    };
    // without branches (`&` on bools): a hop that leaves the grid or meets
    // the other kind or a shorter box stops the joining (and stays on the
    // cell it was on)
    detail::populate(row + d[0] * d[1] * z, static_cast<std::size_t>(d[0] * d[1]));
    for (std::int64_t y = 0; y < d[1]; ++y) {
        const std::int64_t base = d[0] * (y + d[1] * z);
        for (std::int64_t x = 0; x < d[0]; ++x) {
            const std::int64_t i = base + x;
            const std::int64_t c = a == 0 ? x : a == 1 ? y : z;
            const int D = dist[i];
            const std::uint8_t k = kind[i];
            const std::int64_t at1 = c + s * D;
            bool ok = (D < kMaxDistance) & inside(at1);
            const std::int64_t j1 = i + (ok ? s * D * stride : 0);
            const int e1 = dist[j1];
            ok = ok & (kind[j1] == k) & (e1 >= D);
            const int len1 = ok ? std::min(D + e1, kMaxDistance) : D;
            const std::int64_t at2 = at1 + s * e1;
            ok = ok & (len1 < kMaxDistance) & inside(at2);
            const std::int64_t j2 = j1 + (ok ? s * e1 * stride : 0);
            const int e2 = dist[j2];
            ok = ok & (kind[j2] == k) & (e2 >= D);
            row[i] = static_cast<std::uint8_t>(ok ? std::min(len1 + e2, kMaxDistance) : len1);
        }
    }
}

// One pass for octant o, from the far corner of that octant back: the box
// reaching r ahead of m is m and the boxes reaching r − 1 ahead of its 7
// neighbours ahead, so D(m) = 1 + min over them, where a neighbour of the
// other kind (empty or not) counts 0; the grid's outside does not stop a
// box, which is clipped. A plane's row reads the row ahead of it in its own
// plane and the two in the plane ahead, so the planes go in a pipeline: row
// yi of plane zi waits until plane zi − 1 has done its rows 0 … yi.
void EmptySpace::build_ahead(int o, std::uint8_t* out, std::int64_t zi, detail::SharedBuild& job,
                             std::uint8_t* best) const {
    const auto& d = dims_;
    const std::int64_t s[3] = {(o & 1) != 0 ? -1 : 1, (o & 2) != 0 ? -1 : 1, (o & 4) != 0 ? -1 : 1};
    std::uint8_t* ahead = out;                 // every byte written, rows ahead first
    const std::uint8_t* kind = empty_.data();  // 0 or 1: compared as bytes
    const std::atomic<std::int64_t>* before = zi > 0 ? &job.rows[static_cast<std::size_t>(zi - 1)] : nullptr;
    std::atomic<std::int64_t>& done = job.rows[static_cast<std::size_t>(zi)];
    const std::int64_t mz = s[2] > 0 ? d[2] - 1 - zi : zi;  // planes ahead first
    detail::populate(ahead + d[0] * d[1] * mz, static_cast<std::size_t>(d[0] * d[1]));
    for (std::int64_t yi = 0; yi < d[1]; ++yi) {
        if (before != nullptr)
            for (int spin = 0; before->load(std::memory_order_acquire) <= yi; ++spin)
                if (spin >= 64) std::this_thread::yield();
        // rows ahead first: against the octant's direction
        const std::int64_t my = s[1] > 0 ? d[1] - 1 - yi : yi;
        const std::int64_t base = d[0] * (my + d[1] * mz);
        const std::uint8_t* kr = kind + base;
        std::uint8_t* ar = ahead + base;
        std::fill(best, best + d[0], static_cast<std::uint8_t>(kMaxDistance));
        // the 6 neighbours ahead in the rows ahead (bit 0 of e: along x,
        // 1: y, 2: z), which exist unless this row lies on that face, a
        // whole row at a time
        for (int e = 2; e < 8; ++e) {
            if (((e & 2) != 0 && yi == 0) || ((e & 4) != 0 && zi == 0)) continue;
            const std::int64_t dx = (e & 1) != 0 ? s[0] : 0;
            const std::int64_t off =
                dx + ((e & 2) != 0 ? s[1] * d[0] : 0) + ((e & 4) != 0 ? s[2] * d[0] * d[1] : 0);
            const std::uint8_t* kn = kr + off;
            const std::uint8_t* an = ar + off;
            std::uint8_t* b = best;
            // the cells whose neighbour along x is inside the row (best
            // is not the volume's: no dependence between iterations)
#pragma GCC ivdep
            for (std::int64_t x = dx < 0 ? 1 : 0, x1 = dx > 0 ? d[0] - 1 : d[0]; x < x1; ++x) {
                // a neighbour of the other kind stops the box (0xFF
                // where of one kind: no branch, so that it vectorizes)
                const auto same = static_cast<std::uint8_t>(0u - static_cast<unsigned>(kn[x] == kr[x]));
                b[x] = std::min(b[x], static_cast<std::uint8_t>(an[x] & same));
            }
        }
        // then along the row, in the octant's order backwards: the
        // neighbour along x (all but the first cell have one)
        const std::uint8_t* b = best;
        const std::int64_t last = d[0] - 1;
        const auto cell = [&](std::int64_t x, int b_x, std::int64_t next) {
            const int v = std::min(b_x, kr[next] == kr[x] ? static_cast<int>(ar[next]) : 0);
            ar[x] = static_cast<std::uint8_t>(std::min(v + 1, kMaxDistance));
        };
        if (s[0] > 0) {
            ar[last] = static_cast<std::uint8_t>(std::min(b[last] + 1, kMaxDistance));
            for (std::int64_t x = last - 1; x >= 0; --x) cell(x, b[x], x + 1);
        } else {
            ar[0] = static_cast<std::uint8_t>(std::min(b[0] + 1, kMaxDistance));
            for (std::int64_t x = 1; x <= last; ++x) cell(x, b[x], x - 1);
        }
        done.store(yi + 1, std::memory_order_release);
    }
}

void EmptySpace::pixel_bounds(PixelBounds& out, const Camera& camera, int width, int height, const Mat3& axes,
                              const Vec3& origin, int threads, std::size_t boxes_per_thread) const {
    out.clear();
    if (!any_ || width <= 0 || height <= 0) return;
    const Vec3 basis[3] = {camera.right, camera.up, camera.forward};
    for (int a = 0; a < 3; ++a) {
        if (std::abs(dot(basis[a], basis[a]) - 1.0) > 1e-12) return;
        if (std::abs(dot(basis[a], basis[(a + 1) % 3])) > 1e-12) return;
    }
    // Camera coordinates (along right, up, forward) of lattice point q:
    // c0 + Σ_a q_a·col[a].
    const Vec3 c0{dot(origin - camera.position, basis[0]), dot(origin - camera.position, basis[1]),
                  dot(origin - camera.position, basis[2])};
    Vec3 col[3];
    for (int a = 0; a < 3; ++a) {
        const Vec3 e = axes.column(a);
        col[a] = {dot(e, basis[0]), dot(e, basis[1]), dot(e, basis[2])};
    }
    const double m = PixelBounds::kMargin;
    constexpr double kPixelSlack = 1.0 / 16;
    auto corner = [&](const std::array<double, 3>& lo, const std::array<double, 3>& hi, int k) {
        Vec3 c = c0;
        for (int a = 0; a < 3; ++a) c += col[a] * (((k >> a) & 1) != 0 ? hi[a] : lo[a]);
        return c;
    };
    const bool perspective = camera.projection == Projection::perspective;
    // The whole lattice, widened, must lie in front of the camera (no ray
    // starts inside it); its diagonal scales the slack on t.
    double extent = 0.0;
    {
        std::array<double, 3> lo{}, hi{};
        for (int a = 0; a < 3; ++a) {
            lo[a] = -m;
            hi[a] = static_cast<double>(nodes_[a] - 1) + m;
        }
        for (int k = 0; k < 8; ++k) {
            const Vec3 c = corner(lo, hi, k);
            if (!(c.z > 0.0)) return;
            extent = std::max(extent, length(c));
        }
    }
    const double slack = 1e-6 * extent;  // far above the rounding of t here and in the integrators
    const double aspect = static_cast<double>(width) / height;
    const double tan_half = std::tan(camera.fov_y_deg * std::numbers::pi / 360.0);
    // Pixel coordinates of a point c in camera coordinates (Camera::generate
    // solved for (px, py)): px = c.x·s·scale_x + bx, py = by − c.y·s·scale_y with
    // s = 1/c.z (perspective) or 1 (orthographic); rounding differs from
    // the solved form by far less than kPixelSlack.
    const double scale_x = perspective ? width / (2.0 * aspect * tan_half) : width / (aspect * camera.height);
    const double scale_y = perspective ? height / (2.0 * tan_half) : height / camera.height;
    const double bx = width / 2.0 - 0.5, by = height / 2.0 - 0.5;
    // The boxes' images, computed a block at a time in vectors
    // (simd::project_boxes: the corners c of the box, widened by m,
    // projected to pixels, and t along a ray: its camera depth
    // (orthographic), or the distance from the eye (perspective: at least
    // the depth, and at least the centre's distance less the half diagonal;
    // at most the farthest corner's)).
    const simd::BoxProjection projection{
        c0, {col[0], col[1], col[2]}, perspective, scale_x, scale_y, bx, by, shift_, m, dims_, nodes_};
    // The footprint of a box's image (simd::footprint_of): the pixels whose
    // centres fall in it (pixel x's ray projects to x exactly, up to
    // rounding far below kPixelSlack), its t rounded outwards.
    const simd::FootprintRule rule{width, height, kPixelSlack, slack};
    out.width = width;
    const auto pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    // One parallel region: each thread projects a contiguous share of the
    // boxes a block at a time and draws each block's footprints at once
    // into bounds of its own (thread 0 into out's), then the threads merge
    // them, each a contiguous range of pixels. Drawing every box into one
    // pair of arrays made each thread scan every box for its rows: in bands
    // of rows they divided poorly, and dealt out in stripes two threads drew
    // the bunny's 77.5 k boxes in 5.3 ms against one thread's 3.5 ms.
    // Threads: one per boxes_per_thread boxes (16 k: fewer do not pay for
    // their bounds' filling and merging), and as many copies of the bounds
    // as 32 MiB hold (7 at 1024²), two at least.
    const auto copy_bytes = static_cast<std::int64_t>(pixels * 2 * sizeof(float));
    const int nt = static_cast<int>(std::max<std::int64_t>(
        1,
        std::min({static_cast<std::int64_t>(resolve_threads(threads)),
                  1 + static_cast<std::int64_t>(border_.size() / std::max<std::size_t>(1, boxes_per_thread)),
                  std::max<std::int64_t>(2, 1 + (std::int64_t{32} << 20) / copy_bytes)})));
    std::vector<std::vector<float>>&own_lo = out.spare_lo, &own_hi = out.spare_hi;
    own_lo.resize(static_cast<std::size_t>(nt - 1));
    own_hi.resize(own_lo.size());
    parallel_blocks(border_.size(), nt, [&](std::size_t b0, std::size_t b1, int t) {
        std::vector<float>& lo = t == 0 ? out.lo : own_lo[static_cast<std::size_t>(t - 1)];
        std::vector<float>& hi = t == 0 ? out.hi : own_hi[static_cast<std::size_t>(t - 1)];
        lo.assign(pixels, INFINITY);
        hi.assign(pixels, -INFINITY);
        constexpr std::size_t kBlock = 256;
        double images[6][kBlock + 8];  // project_boxes fills whole vectors
        std::int32_t rects[4][kBlock + 16];
        float ts[2][kBlock + 16];  // footprints fills whole vectors too
        const simd::BoxImages im{images[0], images[1], images[2], images[3], images[4], images[5]};
        const simd::Footprints fp{rects[0], rects[1], rects[2], rects[3], ts[0], ts[1]};
        for (std::size_t b = b0; b < b1; b += kBlock) {
            const std::size_t n = std::min(kBlock, b1 - b);
            simd::project_boxes(projection, border_.data() + b, n, im);
            simd::footprints(rule, im, n, fp);
            simd::draw_footprints(fp, n, width, lo.data(), hi.data());
        }
    });
    if (nt > 1)  // min and max in any order: the same bounds as one thread's
        parallel_chunks(static_cast<std::int64_t>(pixels), nt, [&](std::int64_t p0, std::int64_t p1) {
            for (std::size_t t = 0; t < own_lo.size(); ++t) {
                const float* lo = own_lo[t].data();
                const float* hi = own_hi[t].data();
                for (auto i = static_cast<std::size_t>(p0); i < static_cast<std::size_t>(p1); ++i) {
                    out.lo[i] = std::min(out.lo[i], lo[i]);
                    out.hi[i] = std::max(out.hi[i], hi[i]);
                }
            }
        });
}

double EmptySpace::empty_fraction() const {
    if (empty_.empty()) return 0.0;
    std::size_t n = 0;
    for (auto e : empty_) n += e;
    return static_cast<double>(n) / static_cast<double>(empty_.size());
}

double EmptySpace::empty_share_in_pairs() const {
    const MacrocellLattice groups(nodes_, shift_ + 1);
    const std::vector<std::uint8_t> skipped = groups_empty(groups);  // a coarser macrocell skips these too
    std::int64_t total = 0, empty = 0;
    for (std::int64_t z = 0; z < dims_[2]; ++z)
        for (std::int64_t y = 0; y < dims_[1]; ++y)
            for (std::int64_t x = 0; x < dims_[0]; ++x) {
                if (skipped[groups.index({x / 2, y / 2, z / 2})] != 0) continue;
                ++total;
                empty += empty_[index({x, y, z})];
            }
    return total == 0 ? 0.0 : static_cast<double>(empty) / static_cast<double>(total);
}

double EmptySpace::inactive_share(const std::vector<std::uint32_t>& blocks) const {
    // blocks per axis, ⌊nodes / 2⌋ as simd::active_cells counts them
    const std::int64_t bx = nodes_[0] / 2, by = nodes_[1] / 2, bz = nodes_[2] / 2;
    const int per = 1 << (shift_ - 1);  // blocks per macrocell edge
    std::int64_t total = 0, clear = 0;
    for (std::int64_t mz = 0; mz < dims_[2]; ++mz)
        for (std::int64_t my = 0; my < dims_[1]; ++my)
            for (std::int64_t mx = 0; mx < dims_[0]; ++mx) {
                if (empty({mx, my, mz})) continue;
                for (std::int64_t z = mz * per; z < std::min((mz + 1) * per, bz); ++z)
                    for (std::int64_t y = my * per; y < std::min((my + 1) * per, by); ++y)
                        for (std::int64_t x = mx * per; x < std::min((mx + 1) * per, bx); ++x) {
                            const std::int64_t b = x + bx * (y + by * z);
                            ++total;
                            clear +=
                                ((blocks[static_cast<std::size_t>(b >> 5)] >> (b & 31)) & 1u) == 0 ? 1 : 0;
                        }
            }
    return total == 0 ? 0.0 : static_cast<double>(clear) / static_cast<double>(total);
}

}  // namespace fathom
