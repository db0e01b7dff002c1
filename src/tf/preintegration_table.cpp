// Pre-integration tables in O(N²) segment integrals, exactly.
//
// The ramp from v_i to v_j (d = |j − i| grid steps) over a segment of length
// δ crosses the d grid cells between them, each over length δ/d. Its
// (transmittance, radiance) pair is therefore the front-to-back composition
// of the d cell pairs P_k(d) = segment(v_k → v_k±1, δ/d) — exact, since the
// ramp runs at constant speed. For one d every entry is a window of d
// consecutive cell pairs, and the windows slide by one cell: a two-stack
// queue composes each window in O(1) amortised without ever dividing
// (composition has no inverse that is stable near opacity 1). So a table of
// N² entries costs N²/2 cell integrals per direction and O(N²) compositions,
// in the spirit of Lum, Wilson and Ma's incremental subrange integration but
// without its approximation.
#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <vector>

#include "fathom/error.h"
#include "fathom/preintegration.h"

#include "core/parallel.h"
#include "integrate/preintegrated.h"

namespace fathom {
namespace {

// `a` in front of `b` inside one segment: with self-attenuation b's light
// passes a (eq. (16)); without it (eq. (17)) the radiances just add.
struct Over {
    bool attenuate;
    Segment operator()(const Segment& a, const Segment& b) const {
        const double w = attenuate ? a.transmittance : 1.0;
        return {a.transmittance * b.transmittance,
                {a.radiance[0] + w * b.radiance[0], a.radiance[1] + w * b.radiance[1],
                 a.radiance[2] + w * b.radiance[2]}};
    }
};

constexpr Segment kIdentity{1.0, {0, 0, 0}};

// Compositions of every window of d consecutive elements of `cells` (in
// traversal order), written to out[w] for window start w. Two-stack queue.
void window_compositions(const std::vector<Segment>& cells, std::size_t d, const Over& over,
                         std::vector<Segment>& out) {
    std::vector<Segment> front;  // suffix compositions of the oldest elements, oldest on top
    std::vector<Segment> back;   // newest elements
    Segment back_agg = kIdentity;
    out.clear();
    for (std::size_t k = 0; k < cells.size(); ++k) {
        back.push_back(cells[k]);
        back_agg = over(back_agg, cells[k]);
        if (k + 1 < d) continue;
        if (front.empty()) {
            Segment agg = kIdentity;
            for (auto it = back.rbegin(); it != back.rend(); ++it) {
                agg = over(*it, agg);
                front.push_back(agg);
            }
            back.clear();
            back_agg = kIdentity;
        }
        out.push_back(over(front.back(), back_agg));
        front.pop_back();
    }
}

void store(PreintegrationTable& t, int i, int j, const Segment& s) {
    const std::size_t k =
        static_cast<std::size_t>(i) + static_cast<std::size_t>(t.size) * static_cast<std::size_t>(j);
    t.alpha[k] = static_cast<float>(1.0 - s.transmittance);
    for (int c = 0; c < 3; ++c)
        t.color[k * 3 + static_cast<std::size_t>(c)] = static_cast<float>(s.radiance[c]);
}

// The ramp pieces of every grid cell in both directions; they do not
// depend on the segment length, so every distance d reuses them.
struct CellPieces {
    std::vector<RampPiece> pieces;
    std::vector<std::size_t> start;  // cell m's pieces are [start[m], start[m + 1])
};

CellPieces cell_pieces(const PreintegrationTable& t, const Classifier& tf, bool ascending) {
    CellPieces cp;
    const int n = t.size;
    for (int m = 0; m + 1 < n; ++m) {
        // ascending: cell m from v_m to v_m+1; descending: from v_(n−1−m) to v_(n−2−m)
        const int a = ascending ? m : n - 1 - m, b = ascending ? m + 1 : n - 2 - m;
        cp.start.push_back(cp.pieces.size());
        for_each_ramp_piece(tf, t.v(a), t.v(b), [&](const RampPiece& p) { cp.pieces.push_back(p); });
    }
    cp.start.push_back(cp.pieces.size());
    return cp;
}

// All entries with |j − i| = d (d ≥ 1), both directions.
void fill_distance(PreintegrationTable& t, const std::array<CellPieces, 2>& cp, int d,
                   std::vector<Segment>& cells, std::vector<Segment>& windows) {
    const double len = t.delta / d;
    const int n = t.size;
    for (int dir = 0; dir < 2; ++dir) {
        cells.clear();
        const CellPieces& c = cp[static_cast<std::size_t>(dir)];
        for (std::size_t m = 0; m + 1 < c.start.size(); ++m) {
            RampIntegral<Model::emission_absorption> acc(len, t.self_attenuation);
            for (std::size_t p = c.start[m]; p < c.start[m + 1]; ++p) acc.add(c.pieces[p]);
            cells.push_back(acc.result());
        }
        window_compositions(cells, static_cast<std::size_t>(d), Over{t.self_attenuation}, windows);
        for (std::size_t w = 0; w < windows.size(); ++w) {
            const int s = static_cast<int>(w);
            if (dir == 0)
                store(t, s, s + d, windows[w]);
            else
                store(t, n - 1 - s, n - 1 - s - d, windows[w]);
        }
    }
}

}  // namespace

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
    for (int i = 0; i < size; ++i)  // the diagonal: constant segments
        store(t, i, i,
              preintegrate_scalar<Model::emission_absorption>(tf, t.v(i), t.v(i), delta, self_attenuation));
    // Distances are independent; hand them out large-first so the threads finish together.
    const std::array<CellPieces, 2> cp{cell_pieces(t, tf, true), cell_pieces(t, tf, false)};
    std::atomic<int> next{1};
    auto worker = [&] {
        std::vector<Segment> cells, windows;
        for (int d = next++; d < size; d = next++) fill_distance(t, cp, d, cells, windows);
    };
    run_parallel(std::min(resolve_threads(threads), size - 1), [&](int) { worker(); });
    return t;
}

PreintegrationTable build_preintegration_table_direct(const Classifier& tf, double v_lo, double v_hi,
                                                      int size, double delta, bool self_attenuation) {
    PreintegrationTable t = build_preintegration_table(tf, v_lo, v_hi, 2, delta, self_attenuation, 1);
    t.size = size;
    t.alpha.assign(static_cast<std::size_t>(size) * static_cast<std::size_t>(size), 0.0f);
    t.color.assign(t.alpha.size() * 3, 0.0f);
    for (int j = 0; j < size; ++j)
        for (int i = 0; i < size; ++i)
            store(
                t, i, j,
                preintegrate_scalar<Model::emission_absorption>(tf, t.v(i), t.v(j), delta, self_attenuation));
    return t;
}

}  // namespace fathom
