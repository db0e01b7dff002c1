// Highway's foreach_target: this file is compiled once per x86 target and
// preintegrate_batch and preintegrate_pack dispatch at run time (src/integrate/simd_preint.h).
// Every lane performs the scalar code's operations (preintegrated.h's
// for_each_ramp_piece and RampIntegral, preint_piece.h's integrate_piece,
// exp_neg.h) in the same order, the multiply–adds written Fma fused into
// one rounding where it fuses (exp_neg-inl.h); the ramp's cuts, the piece
// chosen and the rules' choices stay the scalar code's operations.
#include "integrate/simd_preint.h"

#include <algorithm>
#include <bit>
#include <cstdint>
#include <vector>

#include "integrate/preint_piece.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "integrate/simd_preint.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "integrate/exp_neg-inl.h"
#include "integrate/gather-inl.h"

HWY_BEFORE_NAMESPACE();
namespace fathom::simd {
namespace HWY_NAMESPACE {
using namespace exp_v;  // hn, the vector types D, V, M, DI, VI and the exponentials

/// The number of keys below v (strict) or at most v, per lane (keys sorted).
template <bool kStrict>
HWY_INLINE VI Count(D d, const std::vector<double>& keys, V v) {
    const DI di;
    if (keys.size() <= 32) return CountKeys<kStrict>(d, keys.data(), keys.size(), v);
    HWY_ALIGN double lanes[hn::MaxLanes(d)];
    HWY_ALIGN std::int64_t counts[hn::MaxLanes(d)];
    hn::Store(v, d, lanes);
    for (std::size_t l = 0; l < hn::Lanes(d); ++l) {
        const auto it = kStrict ? std::lower_bound(keys.begin(), keys.end(), lanes[l])
                                : std::upper_bound(keys.begin(), keys.end(), lanes[l]);
        counts[l] = it - keys.begin();
    }
    return hn::Load(di, counts);
}

/// One piece of a piecewise-linear function per lane, chosen by a value:
/// PiecewiseLinear::piece, then on_piece at any v.
struct Piece {
    V k0, inv, y0[3], y1[3], first[3], last[3];
    M any_below, any_above;

    Piece(D d, const FlatFunction& f, V v) : Piece(d, f, Count<false>(d, f.knots, v)) {}
    /// With p, the number of f's knots ≤ v per lane.
    Piece(D d, const FlatFunction& f, VI p) {
        const DI di;
        const auto n = static_cast<std::int64_t>(f.knots.size());
        const VI lo = hn::Max(hn::Sub(p, hn::Set(di, 1)), hn::Zero(di)), hi = hn::Min(p, hn::Set(di, n - 1));
        if (f.knots.size() <= FlatFunction::kTable && f.knots.size() <= hn::Lanes(d)) {
            // by lane permutation of the padded table: the same values
            const auto ilo = hn::IndicesFromVec(d, lo), ihi = hn::IndicesFromVec(d, hi);
            const V knots = hn::LoadU(d, f.table[0]);
            k0 = hn::TableLookupLanes(knots, ilo);
            inv = hn::TableLookupLanes(hn::LoadU(d, f.table[FlatFunction::kInvRow]), ilo);
            for (int c = 0; c < f.components; ++c) {
                const V y = hn::LoadU(d, f.table[1 + c]);
                y0[c] = hn::TableLookupLanes(y, ilo);
                y1[c] = hn::TableLookupLanes(y, ihi);
            }
        } else {
            k0 = gather::Doubles(d, f.knots.data(), lo);
            inv = gather::Doubles(d, f.inv.data(), lo);
            for (int c = 0; c < f.components; ++c) {
                y0[c] = gather::Doubles(d, f.y[c].data(), lo);
                y1[c] = gather::Doubles(d, f.y[c].data(), hi);
            }
        }
        for (int c = 0; c < f.components; ++c) {
            first[c] = hn::Set(d, f.y[c].front());
            last[c] = hn::Set(d, f.y[c].back());
        }
        any_below = hn::RebindMask(d, hn::Gt(p, hn::Zero(di)));
        any_above = hn::RebindMask(d, hn::Lt(p, hn::Set(di, n)));
    }
    /// The position of v on the piece (on_piece's w, once for all components).
    [[nodiscard]] V weight(V v) const { return PiecePosition(v, k0, inv); }
    /// Component c at the position w (on_piece: the ends' values before and after the knots).
    [[nodiscard]] V at(int c, V w) const {
        const V r = Fma(w, hn::Sub(y1[c], y0[c]), y0[c]);
        return hn::IfThenElse(any_below, hn::IfThenElse(any_above, r, last[c]), first[c]);
    }
};

/// A piece's integrals per lane (integrate_piece), and lanes it leaves to
/// the scalar code.
struct PieceOut {
    V depth, radiance[3];
    M scalar;
};

/// integrate_piece(len, s0, s1, g = a + b·u + c·u², full) per lane.
HWY_INLINE PieceOut IntegratePiece(D d, V len, V s0, V s1, const V* a, const V* b, const V* c, bool full) {
    using namespace preint::detail;
    PieceOut o;
    o.depth = hn::Mul(hn::Mul(len, hn::Set(d, 0.5)), hn::Add(s0, s1));
    o.scalar = hn::FirstN(d, 0);
    if (!full) {  // eq. (17)
        for (int k = 0; k < 3; ++k)
            o.radiance[k] = hn::Mul(
                len, hn::Add(hn::Add(a[k], hn::Div(b[k], hn::Set(d, 2.0))), hn::Div(c[k], hn::Set(d, 3.0))));
        return o;
    }
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0);
    M constant = hn::Eq(s0, s1);
    for (int k = 0; k < 3; ++k) constant = hn::And(constant, hn::And(hn::Eq(b[k], zero), hn::Eq(c[k], zero)));
    // a constant piece: g·(1 − e^{−σ len})/σ, or g·len where σ = 0
    const M absorbing = hn::And(constant, hn::Gt(s0, zero));
    V weight = len;
    if (!hn::AllFalse(d, absorbing)) {
        const V x = hn::Mul(s0, len);
        o.scalar = hn::AndNot(InRange(d, x), absorbing);
        weight = hn::IfThenElse(absorbing, hn::Div(OneMinusExpNeg(d, x), s0), len);
    }
    const V A = hn::Mul(len, s0), B = hn::Mul(hn::Mul(len, hn::Set(d, 0.5)), hn::Sub(s1, s0));
    auto tau = [&](V u) { return hn::Mul(u, Fma(B, u, A)); };
    auto source = [&](int k, V u) { return Fma(u, Fma(u, c[k], b[k]), a[k]); };
    const M shallow = hn::Le(o.depth, hn::Set(d, kThin));
    V thin[3] = {zero, zero, zero};
    if (!hn::AllFalse(d, hn::AndNot(constant, shallow))) {  // some lane takes the thin rule
        for (std::size_t q = 0; q < 3; ++q) {
            const V u = hn::Set(d, kX3[q]);
            const V w = hn::Mul(hn::Mul(len, hn::Set(d, kW3[q])), ExpNegThin(d, tau(u)));  // τ ≤ kThin
            for (int k = 0; k < 3; ++k) thin[k] = Fma(w, source(k, u), thin[k]);
        }
    }
    const M deep = hn::AndNot(constant, hn::Not(shallow));
    o.scalar = hn::Or(o.scalar, hn::AndNot(constant, hn::Not(hn::Le(o.depth, hn::Set(d, kMaxDepth)))));
    V thick[3] = {zero, zero, zero};
    const M chunked = hn::AndNot(o.scalar, deep);
    if (!hn::AllFalse(d, chunked)) {
        // sub-intervals of optical depth ≤ 1: total = depth ≤ kMaxDepth, so
        // the last ends at u = 1
        const V total =
            hn::IfThenElse(hn::Lt(hn::Set(d, kMaxDepth), o.depth), hn::Set(d, kMaxDepth), o.depth);
        const V chunks = hn::IfThenElse(chunked, hn::Max(one, hn::Ceil(total)), zero);
        HWY_ALIGN double count[hn::MaxLanes(d)];
        hn::Store(chunks, d, count);
        const double most = *std::max_element(count, count + hn::Lanes(d));
        auto u_at = [&](V level) {  // τ(u) = level
            const V linear = hn::Div(level, A);
            V disc = Fma(hn::Mul(hn::Set(d, 4.0), B), level, hn::Mul(A, A));
            disc = hn::IfThenElse(hn::Lt(zero, disc), disc, zero);
            const V root = hn::Div(hn::Mul(hn::Set(d, 2.0), level), hn::Add(A, hn::Sqrt(disc)));
            const V u = hn::IfThenElse(hn::Eq(B, zero), linear, root);
            return hn::IfThenElse(hn::Lt(u, one), u, one);  // min_of(1, u)
        };
        V u0 = zero;
        for (double m = 1; m <= most; ++m) {
            const V mv = hn::Set(d, m);
            const M in = hn::Le(mv, chunks);
            // the last sub-interval of every lane in it ends at u = 1: no root to find
            const M last = hn::Eq(mv, chunks);
            const V u1 = hn::AllFalse(d, hn::AndNot(last, in))
                             ? one
                             : hn::IfThenElse(last, one, u_at(hn::Div(hn::Mul(total, mv), chunks)));
            const V du = hn::Sub(u1, u0);
            for (std::size_t q = 0; q < 6; ++q) {
                const V u = Fma(du, hn::Set(d, kX[q]), u0);
                const V w = hn::Mul(hn::Mul(hn::Mul(len, du), hn::Set(d, kW[q])), ExpNegOf(d, tau(u), in));
                for (int k = 0; k < 3; ++k)
                    thick[k] = hn::IfThenElse(in, Fma(w, source(k, u), thick[k]), thick[k]);
            }
            u0 = hn::IfThenElse(in, u1, u0);
        }
    }
    for (int k = 0; k < 3; ++k)
        o.radiance[k] =
            hn::IfThenElse(constant, hn::Mul(a[k], weight), hn::IfThenElse(deep, thick[k], thin[k]));
    return o;
}

/// Segments vf → vb per lane, where `ok`: the transmittance T, the radiance
/// E, and the lanes left to the scalar code (those not `ok` among them).
struct Segments {
    V T, E[3];
    M scalar;
};

/// A vector of ramps vf → vb over vdelta (preintegrate_scalar's
/// RampIntegral over for_each_ramp_piece), part way: the pieces before
/// piece lead + m added (E, depth, T), l0 where the next one starts.
struct Ramp {
    V vf, vb, vdelta, l0;
    VI first, lead, cuts, rounds;  // pieces lead … lead + rounds remain
    V E[3], depth, T;
    M ok, scalar;  // scalar: left to the scalar code (those not `ok` among them)
};

/// l at the cut ending piece m of each lane's ramp, where `cut` (1 past the last cut).
HWY_INLINE V CutAt(D d, const BatchSource& src, const Ramp& r, VI m, M cut) {
    const DI di;
    const std::vector<double>& breaks = *src.breaks;
    const auto nb = static_cast<std::int64_t>(breaks.size());
    VI at = hn::IfThenElse(hn::RebindMask(di, hn::Lt(r.vf, r.vb)), hn::Add(r.first, m), hn::Sub(r.first, m));
    at = hn::Min(hn::Max(at, hn::Zero(di)), hn::Set(di, nb - 1));
    const V knot = src.break_table != nullptr && breaks.size() <= hn::Lanes(d)
                       ? hn::TableLookupLanes(hn::Load(d, src.break_table), hn::IndicesFromVec(d, at))
                       : gather::Doubles(d, breaks.data(), at);
    return hn::IfThenElse(cut, hn::Div(hn::Sub(knot, r.vf), hn::Sub(r.vb, r.vf)),
                          hn::Set(d, 1.0));  // = (vf − k)/(vf − vb)
}

/// The ramps of the lanes `ok`, before their first piece.
HWY_INLINE Ramp StartRamp(D d, const BatchSource& src, V vdelta, V vf, V vb, M ok) {
    const DI di;
    const std::vector<double>& breaks = *src.breaks;
    const V zero = hn::Zero(d);
    Ramp r;
    r.vf = vf;
    r.vb = vb;
    r.vdelta = vdelta;
    r.ok = ok;
    // the control values strictly between the ends, in the order the ramp meets them
    const M ascending = hn::Lt(vf, vb);
    const V lo = hn::IfThenElse(ascending, vf, vb), hi = hn::IfThenElse(ascending, vb, vf);
    const VI below_hi = Count<true>(d, breaks, hi), upto_lo = Count<false>(d, breaks, lo);
    r.cuts = hn::IfThenElseZero(hn::RebindMask(di, hn::And(ok, hn::Ne(vf, vb))), hn::Sub(below_hi, upto_lo));
    // the first cut: the first knot > vf (ascending) or the last < vf
    r.first = hn::IfThenElse(hn::RebindMask(di, ascending), upto_lo, hn::Sub(below_hi, hn::Set(di, 1)));
    // Pieces wholly below the medium's zero range add nothing: their σ and
    // g are exactly zero, so E and the depth stay, and so does T = e^{−depth}
    // (1 before the first piece). The ramp leaves them out: those that end
    // at a cut at or below zero_below, before the first piece (ascending) or
    // after the last (descending). Pieces m = lead … lead + rounds remain.
    const auto at_most_e = static_cast<std::int64_t>(
        std::upper_bound(breaks.begin(), breaks.end(), src.zero_below) - breaks.begin());
    const VI zeros = hn::Min(hn::Max(hn::Sub(hn::Set(di, at_most_e), upto_lo), hn::Zero(di)), r.cuts);
    r.lead = hn::IfThenElseZero(hn::RebindMask(di, ascending), zeros);
    r.rounds = hn::Sub(r.cuts, zeros);
    for (V& e : r.E) e = zero;
    r.depth = zero;
    r.T = hn::Set(d, 1.0);
    const M skips = hn::And(ok, hn::RebindMask(d, hn::Lt(hn::Zero(di), r.lead)));
    r.l0 = hn::AllFalse(d, skips)
               ? zero
               : hn::IfThenElse(skips, CutAt(d, src, r, hn::Sub(r.lead, hn::Set(di, 1)), skips), zero);
    r.scalar = hn::Not(ok);
    return r;
}

/// The most pieces after the first of any lane of r.
HWY_INLINE std::int64_t MostRounds(D d, const Ramp& r) {
    const DI di;
    HWY_ALIGN std::int64_t round_count[hn::MaxLanes(d)];
    hn::Store(r.rounds, di, round_count);
    return *std::max_element(round_count, round_count + hn::Lanes(d));
}

/// Adds piece lead + m of each lane that has it (for_each_ramp_piece's
/// piece(l0, l1), then RampIntegral::add).
HWY_INLINE void AddPiece(D d, const BatchSource& src, bool shared, Model model, bool full, Ramp& r,
                         std::int64_t m) {
    const DI di;
    const bool absorb = model != Model::emission, source = model != Model::absorption;
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0);
    const V span = hn::Sub(r.vb, r.vf), vf = r.vf;
    const M active = hn::And(r.ok, hn::RebindMask(d, hn::Lt(hn::Set(di, m - 1), r.rounds)));
    const VI piece = hn::Add(r.lead, hn::Set(di, m));
    const M cut = hn::And(active, hn::RebindMask(d, hn::Lt(piece, r.cuts)));
    const V l0 = r.l0, l1 = hn::AllFalse(d, cut) ? one : CutAt(d, src, r, piece, cut);
    // for_each_ramp_piece's piece(l0, l1)
    const V v0 = hn::Add(vf, hn::Mul(l0, span)), v1 = hn::Add(vf, hn::Mul(l1, span));
    const V vm = hn::Mul(hn::Set(d, 0.5), hn::Add(v0, v1));
    // (σ's knots shared by c: one count, the same positions)
    const VI at_vm = Count<false>(d, src.sigma->knots, vm);
    const Piece ps(d, *src.sigma, at_vm),
        pc = shared ? Piece(d, *src.color, at_vm) : Piece(d, *src.color, vm);
    const V ws0 = ps.weight(v0), ws1 = ps.weight(v1);
    V s0 = ps.at(0, ws0), s1 = ps.at(0, ws1);
    const V w0 = shared ? ws0 : pc.weight(v0), w1 = shared ? ws1 : pc.weight(v1);
    V a[3], bq[3], cq[3];
    for (int k = 0; k < 3; ++k) {
        const V c0 = pc.at(k, w0), c1 = pc.at(k, w1);
        if (!source) {
            a[k] = bq[k] = cq[k] = zero;
        } else if (src.associated) {  // emission_source
            a[k] = c0;
            bq[k] = hn::Sub(c1, c0);
            cq[k] = zero;
        } else {  // particle_source
            a[k] = hn::Mul(s0, c0);
            bq[k] = Fma(s0, hn::Sub(c1, c0), hn::Mul(c0, hn::Sub(s1, s0)));
            cq[k] = hn::Mul(hn::Sub(s1, s0), hn::Sub(c1, c0));
        }
    }
    if (!absorb) s0 = s1 = zero;
    // RampIntegral::add
    const PieceOut o = IntegratePiece(d, hn::Mul(hn::Sub(l1, l0), r.vdelta), s0, s1, a, bq, cq, full);
    for (int k = 0; k < 3; ++k)
        r.E[k] = hn::IfThenElse(active, Fma(full ? r.T : one, o.radiance[k], r.E[k]), r.E[k]);
    r.depth = hn::IfThenElse(active, hn::Add(r.depth, o.depth), r.depth);
    r.scalar = hn::Or(r.scalar, hn::And(active, hn::Or(o.scalar, hn::Not(InRange(d, r.depth)))));
    r.T = hn::IfThenElse(active, ExpNegOf(d, r.depth, hn::FirstN(d, hn::Lanes(d))), r.T);
    r.l0 = l1;
}

/// The lanes' segments from their ramp pieces (preintegrate_scalar's
/// RampIntegral over for_each_ramp_piece).
HWY_NOINLINE Segments RampSegments(D d, const BatchSource& src, bool shared, Model model, bool full, V vdelta,
                                   V vf, V vb, M ok) {
    Ramp r = StartRamp(d, src, vdelta, vf, vb, ok);
    const std::int64_t most = MostRounds(d, r);
    for (std::int64_t m = 0; m <= most; ++m) AddPiece(d, src, shared, model, full, r, m);
    return {r.T, {r.E[0], r.E[1], r.E[2]}, r.scalar};
}

/// One column of the integral functions at rows p (a lane permutation of
/// the padded column where the rows fit in a vector).
HWY_INLINE V Column(D d, const IntegralFunctions& f, std::size_t c, VI p) {
    if (f.rows() <= hn::Lanes(d))
        return hn::TableLookupLanes(hn::LoadU(d, f.col[c].data()), hn::IndicesFromVec(d, p));
    return gather::Doubles(d, f.col[c].data(), p);
}

/// The integral functions S and G (IntegralFunctions) at v per lane.
HWY_INLINE void EndIntegrals(D d, const IntegralFunctions& f, bool absorb, bool source, V v, V& S, V* G) {
    using F = IntegralFunctions;
    const VI p = Count<false>(d, f.knots, v);
    const V x = hn::Sub(v, Column(d, f, F::kStart, p)), w = hn::Mul(x, Column(d, f, F::kInvWidth, p));
    if (absorb)
        S = Fma(x, Fma(Column(d, f, F::kHalfRise, p), w, Column(d, f, F::kSigma, p)), Column(d, f, F::kS, p));
    if (source)
        for (std::size_t k = 0; k < 3; ++k) {
            const V c = Fma(w, Column(d, f, F::kC + k, p), Column(d, f, F::kB + k, p));
            const V a = Fma(w, c, Column(d, f, F::kA + k, p));
            G[k] = Fma(x, a, Column(d, f, F::kG + k, p));
        }
}

/// The segments vf → vb over vdelta of the lanes `ok` (the others flagged
/// scalar); with integral functions `f` (without self-attenuation), S and G
/// at the two ends (Sf, Sb, Gf, Gb).
HWY_INLINE Segments SegmentsOf(D d, const BatchSource& src, Model model, bool full,
                               const IntegralFunctions* f, V vdelta, V vf, V vb, M ok, V Sf, V Sb,
                               const V* Gf, const V* Gb) {
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0);
    const bool absorb = model != Model::emission, source = model != Model::absorption;
    const bool shared = src.shared_knots;
    if (f == nullptr) return RampSegments(d, src, shared, model, full, vdelta, vf, vb, ok);
    // steep_ramp and integral_segment per lane
    const V k0 = hn::Set(d, f->knots.front()), flat = hn::Set(d, preint::kFlatRamp);
    Segments r;
    const V dv = hn::Sub(vb, vf);
    const M steep = hn::And(
        ok, hn::Gt(hn::Abs(dv), hn::Mul(flat, hn::Add(hn::Abs(hn::Sub(vf, k0)), hn::Abs(hn::Sub(vb, k0))))));
    const M pieces = hn::AndNot(steep, ok);  // the lanes that take the ramp's pieces
    const V ratio = hn::Div(vdelta, dv);
    r.T = one;
    r.scalar = hn::Not(ok);
    if (absorb) {
        V tau = hn::Mul(hn::Sub(Sb, Sf), ratio);
        tau = hn::IfThenElse(hn::Gt(tau, zero), tau, zero);
        r.scalar = hn::Or(r.scalar, hn::AndNot(InRange(d, tau), steep));
        r.T = ExpNeg(d, tau);
    }
    for (std::size_t k = 0; k < 3; ++k)
        r.E[k] = source ? hn::Add(hn::Mul(hn::Sub(Gb[k], Gf[k]), ratio), zero) : zero;
    if (!hn::AllFalse(d, pieces)) {
        const Segments p = RampSegments(d, src, shared, model, full, vdelta, vf, vb, pieces);
        r.T = hn::IfThenElse(pieces, p.T, r.T);
        for (std::size_t k = 0; k < 3; ++k) r.E[k] = hn::IfThenElse(pieces, p.E[k], r.E[k]);
        r.scalar = hn::Or(hn::AndNot(pieces, r.scalar), hn::And(pieces, p.scalar));
    }
    return r;
}

/// The integral functions of a batch source without self-attenuation, or null.
inline const IntegralFunctions* integrals_of(const BatchSource& src, bool full) {
    return !full && src.integrals != nullptr && !src.integrals->empty() ? src.integrals : nullptr;
}

void PreintegrateBatch(const BatchSource& src, Model model, bool full, double delta, const double* ends,
                       int count, std::uint32_t skip, SegmentBatch& out) {
    const D d;
    const std::size_t N = hn::Lanes(d);
    const V zero = hn::Zero(d), vdelta = hn::Set(d, delta);
    const auto segments = static_cast<std::size_t>(std::max(count - 1, 0));
    out.scalar = ~std::uint32_t{0};
    if (src.sigma->knots.empty() || src.color->knots.empty()) return;  // nothing to select from
    // Without self-attenuation: S and G at every end once (integral_segment).
    const IntegralFunctions* f = integrals_of(src, full);
    HWY_ALIGN double S[kBatch + 2 * hn::MaxLanes(d)], G[3][kBatch + 2 * hn::MaxLanes(d)];
    const bool absorb = model != Model::emission, source = model != Model::absorption;
    if (f != nullptr) {
        const auto n = static_cast<std::size_t>(count);
        std::size_t e = 0;
        for (; e < n; e += N) {
            V s = zero, g[3] = {zero, zero, zero};
            EndIntegrals(d, *f, absorb, source, hn::LoadU(d, ends + e), s, g);
            hn::Store(s, d, S + e);
            for (std::size_t k = 0; k < 3; ++k) hn::Store(g[k], d, G[k] + e);
        }
        // the lanes past the last end: read by the last vector of segments, never used
        hn::Store(zero, d, S + e);
        for (auto& g : G) hn::Store(zero, d, g + e);
    }
    for (std::size_t b = 0; b < segments; b += N) {
        // the segments b … b + N − 1 wanted: not skipped, before the last
        const std::size_t in = std::min(N, segments - b);
        const std::uint32_t lanes = (std::uint32_t{1} << in) - 1u;  // in ≤ 8
        const auto wanted = static_cast<std::uint8_t>(~(skip >> b) & lanes);
        if (wanted == 0) continue;
        const V vf = hn::LoadU(d, ends + b), vb = hn::LoadU(d, ends + b + 1);
        const M ok = hn::And(hn::LoadMaskBits(d, &wanted), hn::And(hn::IsFinite(vf), hn::IsFinite(vb)));
        V Sf = zero, Sb = zero, Gf[3] = {zero, zero, zero}, Gb[3] = {zero, zero, zero};
        if (f != nullptr) {
            Sf = hn::LoadU(d, S + b);
            Sb = hn::LoadU(d, S + b + 1);
            for (std::size_t k = 0; k < 3; ++k) {
                Gf[k] = hn::LoadU(d, G[k] + b);
                Gb[k] = hn::LoadU(d, G[k] + b + 1);
            }
        }
        const Segments r = SegmentsOf(d, src, model, full, f, vdelta, vf, vb, ok, Sf, Sb, Gf, Gb);
        hn::Store(r.T, d, out.transmittance + b);
        for (int k = 0; k < 3; ++k) hn::Store(r.E[k], d, out.radiance[k] + b);
        std::uint8_t bits[8] = {};
        hn::StoreMaskBits(d, hn::Not(r.scalar), bits);
        out.scalar &= ~(static_cast<std::uint32_t>(bits[0]) << b);
    }
}

/// Ramps lane by lane: those of a pack that go on past their first piece,
/// gathered from the pack's vectors into whole ones (slot: the segment's
/// place in the pack), or one vector's.
template <std::size_t kSize>
struct RampLanes {
    HWY_ALIGN double vf[kSize], vb[kSize], delta[kSize], l0[kSize], E[3][kSize], depth[kSize], T[kSize];
    HWY_ALIGN double scalar[kSize];
    HWY_ALIGN std::int64_t first[kSize], lead[kSize], cuts[kSize], rounds[kSize], slot[kSize];
    std::size_t count = 0;
};

/// Stores r's lanes into `at` (arrays of whole vectors, from lane 0 on).
template <std::size_t kSize>
HWY_INLINE void StoreRamp(D d, const Ramp& r, RampLanes<kSize>& at, std::size_t b) {
    const DI di;
    hn::Store(r.vf, d, at.vf + b);
    hn::Store(r.vb, d, at.vb + b);
    hn::Store(r.vdelta, d, at.delta + b);
    hn::Store(r.l0, d, at.l0 + b);
    for (int k = 0; k < 3; ++k) hn::Store(r.E[k], d, at.E[k] + b);
    hn::Store(r.depth, d, at.depth + b);
    hn::Store(r.T, d, at.T + b);
    hn::Store(hn::IfThenElseZero(r.scalar, hn::Set(d, 1.0)), d, at.scalar + b);
    hn::Store(r.first, di, at.first + b);
    hn::Store(r.lead, di, at.lead + b);
    hn::Store(r.cuts, di, at.cuts + b);
    hn::Store(r.rounds, di, at.rounds + b);
}

/// The lanes b … b + N − 1 of `at` that `ok` holds (the first ones), the
/// others zeros with T = 1, as in a pack's last vector: StoreRamp's inverse.
template <std::size_t kSize>
HWY_INLINE Ramp LoadRamp(D d, const RampLanes<kSize>& at, std::size_t b, M ok) {
    const DI di;
    const auto oki = hn::RebindMask(di, ok);
    Ramp r;
    r.ok = ok;
    r.vf = hn::IfThenElseZero(ok, hn::Load(d, at.vf + b));
    r.vb = hn::IfThenElseZero(ok, hn::Load(d, at.vb + b));
    r.vdelta = hn::IfThenElseZero(ok, hn::Load(d, at.delta + b));
    r.l0 = hn::IfThenElseZero(ok, hn::Load(d, at.l0 + b));
    for (int k = 0; k < 3; ++k) r.E[k] = hn::IfThenElseZero(ok, hn::Load(d, at.E[k] + b));
    r.depth = hn::IfThenElseZero(ok, hn::Load(d, at.depth + b));
    r.T = hn::IfThenElse(ok, hn::Load(d, at.T + b), hn::Set(d, 1.0));
    r.scalar = hn::Ne(hn::Load(d, at.scalar + b), hn::Zero(d));
    r.first = hn::IfThenElseZero(oki, hn::Load(di, at.first + b));
    r.lead = hn::IfThenElseZero(oki, hn::Load(di, at.lead + b));
    r.cuts = hn::IfThenElseZero(oki, hn::Load(di, at.cuts + b));
    r.rounds = hn::IfThenElseZero(oki, hn::Load(di, at.rounds + b));
    return r;
}

/// Copies lane i of `from` to lane j of `to` (j ≤ i where they are one).
template <std::size_t kFrom, std::size_t kTo>
HWY_INLINE void MoveLane(const RampLanes<kFrom>& from, std::size_t i, RampLanes<kTo>& to, std::size_t j) {
    to.vf[j] = from.vf[i];
    to.vb[j] = from.vb[i];
    to.delta[j] = from.delta[i];
    to.l0[j] = from.l0[i];
    for (int k = 0; k < 3; ++k) to.E[k][j] = from.E[k][i];
    to.depth[j] = from.depth[i];
    to.T[j] = from.T[i];
    to.scalar[j] = from.scalar[i];
    to.first[j] = from.first[i];
    to.lead[j] = from.lead[i];
    to.cuts[j] = from.cuts[i];
    to.rounds[j] = from.rounds[i];
    to.slot[j] = from.slot[i];
}

void PreintegratePack(const BatchSource& src, Model model, bool full, SegmentPack& pack, int first) {
    const D d;
    const DI di;
    const std::size_t N = hn::Lanes(d);
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0);
    const auto n = static_cast<std::size_t>(pack.count);
    const auto b0 = static_cast<std::size_t>(first);
    if (src.sigma->knots.empty() || src.color->knots.empty()) {  // nothing to select from
        std::fill(pack.scalar + b0, pack.scalar + n, 1.0);
        return;
    }
    const IntegralFunctions* f = integrals_of(src, full);
    const bool absorb = model != Model::emission, source = model != Model::absorption;
    if (f == nullptr && n - b0 > 2 * N) {
        // Every segment takes its ramp's pieces, in more than two vectors:
        // each vector adds its lanes' first pieces; the lanes with more go
        // on together, gathered into whole vectors, a piece at a time (the
        // same operations per lane as RampSegments' rounds, so the same
        // bits). (In two vectors or fewer, each does all its rounds: too few
        // lanes go on to fill a vector.)
        RampLanes<SegmentPack::kPadded> more;
        RampLanes<hn::MaxLanes(d)> lanes;
        for (std::size_t b = b0; b < n; b += N) {
            const M in = hn::FirstN(d, n - b);  // the lanes past the last: zeros, not used
            const V vf = hn::IfThenElseZero(in, hn::Load(d, pack.vf + b)),
                    vb = hn::IfThenElseZero(in, hn::Load(d, pack.vb + b));
            const M ok = hn::And(in, hn::And(hn::IsFinite(vf), hn::IsFinite(vb)));
            Ramp r = StartRamp(d, src, hn::IfThenElseZero(in, hn::Load(d, pack.delta + b)), vf, vb, ok);
            AddPiece(d, src, src.shared_knots, model, full, r, 0);
            hn::Store(r.T, d, pack.transmittance + b);
            for (int k = 0; k < 3; ++k) hn::Store(r.E[k], d, pack.radiance[k] + b);
            hn::Store(hn::IfThenElseZero(r.scalar, one), d, pack.scalar + b);
            const M on = hn::And(ok, hn::RebindMask(d, hn::Lt(hn::Zero(di), r.rounds)));
            if (hn::AllFalse(d, on)) continue;
            StoreRamp(d, r, lanes, 0);
            std::uint8_t bits[8] = {};
            hn::StoreMaskBits(d, on, bits);
            for (unsigned left = bits[0]; left != 0; left &= left - 1) {
                const auto l = static_cast<std::size_t>(std::countr_zero(left));
                lanes.slot[l] = static_cast<std::int64_t>(b + l);
                MoveLane(lanes, l, more, more.count++);
            }
        }
        for (std::int64_t m = 1; more.count > 0; ++m) {
            const std::size_t count = more.count;
            more.count = 0;  // the lanes that go on after this round, in place
            for (std::size_t b = 0; b < count; b += N) {
                Ramp r = LoadRamp(d, more, b, hn::FirstN(d, count - b));
                AddPiece(d, src, src.shared_knots, model, full, r, m);
                StoreRamp(d, r, lanes, 0);
                const std::size_t in = std::min(N, count - b);
                for (std::size_t l = 0; l < in; ++l) {
                    lanes.slot[l] = more.slot[b + l];
                    const auto k = static_cast<std::size_t>(lanes.slot[l]);
                    pack.transmittance[k] = lanes.T[l];
                    for (int c = 0; c < 3; ++c) pack.radiance[c][k] = lanes.E[c][l];
                    pack.scalar[k] = lanes.scalar[l];
                    if (lanes.rounds[l] > m) MoveLane(lanes, l, more, more.count++);
                }
            }
        }
        return;
    }
    for (std::size_t b = b0; b < n; b += N) {
        const M in = hn::FirstN(d, n - b);  // the lanes past the last: zeros, not used
        const V vf = hn::IfThenElseZero(in, hn::Load(d, pack.vf + b)),
                vb = hn::IfThenElseZero(in, hn::Load(d, pack.vb + b));
        const M ok = hn::And(in, hn::And(hn::IsFinite(vf), hn::IsFinite(vb)));
        V Sf = zero, Sb = zero, Gf[3] = {zero, zero, zero}, Gb[3] = {zero, zero, zero};
        if (f != nullptr) {
            EndIntegrals(d, *f, absorb, source, vf, Sf, Gf);
            EndIntegrals(d, *f, absorb, source, vb, Sb, Gb);
        }
        const Segments r =
            SegmentsOf(d, src, model, full, f, hn::IfThenElseZero(in, hn::Load(d, pack.delta + b)), vf, vb,
                       ok, Sf, Sb, Gf, Gb);
        hn::Store(r.T, d, pack.transmittance + b);
        for (int k = 0; k < 3; ++k) hn::Store(r.E[k], d, pack.radiance[k] + b);
        hn::Store(hn::IfThenElseZero(r.scalar, one), d, pack.scalar + b);
    }
}

// NOLINTNEXTLINE(google-readability-namespace-comments)
}  // namespace HWY_NAMESPACE
}  // namespace fathom::simd
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fathom::simd {

HWY_EXPORT(PreintegrateBatch);
HWY_EXPORT(PreintegratePack);

void preintegrate_batch(const BatchSource& src, Model model, bool full, double delta, const double* ends,
                        int count, std::uint32_t skip, SegmentBatch& out) {
    HWY_DYNAMIC_DISPATCH(PreintegrateBatch)(src, model, full, delta, ends, count, skip, out);
}

void preintegrate_pack(const BatchSource& src, Model model, bool full, SegmentPack& pack, int first) {
    HWY_DYNAMIC_DISPATCH(PreintegratePack)(src, model, full, pack, first);
}

}  // namespace fathom::simd
#endif
