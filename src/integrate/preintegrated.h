// `preintegrated` and `preintegrated-simple`: pre-integrated classification
// (docs/theory.md eqs. (15)–(18)). The scalar is sampled at the n + 1
// segment ends and taken as linear within a segment; each segment's opacity
// and radiance are the exact integrals of the transfer function along that
// linear ramp.
//
// Evaluation: the ramp is cut at every transfer-function control value it
// crosses, so that σ, c and q are linear in the ramp parameter l on every
// piece (one-sided limits at jumps come from choosing the piece). On a piece
// the optical depth and the radiance without self-attenuation have closed
// forms; the radiance with self-attenuation, ∫ g(l)·exp(−τ(l)) dl, is
// integrated by Gauss–Legendre on sub-pieces of optical depth ≤ 1, which is
// accurate to about 1e−10 of the segment's radiance for every segment length
// (and exact where the piece is constant: then it equals the alpha
// quadrature). Without self-attenuation the sums over the pieces are
// differences of the integral functions S and G (Classifier::integrals),
// which preint::integral_segment takes wherever the ramp is not too flat
// for the difference. Pre-classified grids take σ and c linear along the
// segment between their end samples: one piece.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <optional>

#include "integrate/accumulator.h"
#include "integrate/exp_neg.h"
#include "integrate/ray_span.h"
#include "integrate/simd_classify.h"
#include "integrate/simd_preint.h"
#include "render/empty_space.h"
#include "render/shading.h"

namespace fathom {
namespace preint {

/// The source on a piece as a quadratic in u ∈ [0, 1], per channel: g = a + b·u + c·u².
/// S is double, or a dual number where derivatives are wanted (src/diff/).
template <class S>
struct QuadraticT {
    std::array<S, 3> a{}, b{}, c{};
};
using Quadratic = QuadraticT<double>;

/// Particle model: g = σ(u)·c(u) with σ and c linear.
template <class S>
QuadraticT<S> particle_source(const S& s0, const S& s1, const std::array<S, 3>& c0,
                              const std::array<S, 3>& c1) {
    QuadraticT<S> q;
    for (int k = 0; k < 3; ++k) {
        q.a[k] = s0 * c0[k];
        q.b[k] = s0 * (c1[k] - c0[k]) + c0[k] * (s1 - s0);
        q.c[k] = (s1 - s0) * (c1[k] - c0[k]);
    }
    return q;
}

/// Associated emission: g = q(u), linear.
template <class S>
QuadraticT<S> emission_source(const std::array<S, 3>& q0, const std::array<S, 3>& q1) {
    QuadraticT<S> q;
    for (int k = 0; k < 3; ++k) {
        q.a[k] = q0[k];
        q.b[k] = q1[k] - q0[k];
    }
    return q;
}

template <class S>
struct PieceIntegralT {
    S depth = 0;                  // τ = ∫ σ_a over the piece
    std::array<S, 3> radiance{};  // E = ∫ g·exp(−∫σ_a) over the piece (or ∫ g without self-attenuation)
};
using PieceIntegral = PieceIntegralT<double>;

/// One piece of world length `len`, σ_a linear from s0 to s1, source g.
PieceIntegral integrate_piece(double len, double s0, double s1, const Quadratic& g, bool self_attenuation);

}  // namespace preint

/// A piece of a ramp on which σ and the source are linear/quadratic in l:
/// fraction dl of the ramp, σ from s0 to s1, source g (particle or emission).
struct RampPiece {
    double dl;
    double s0, s1;
    preint::Quadratic g;
};

/// Calls f(RampPiece) for each piece of the ramp v_front → v_back, cut at
/// every transfer-function control value strictly between them, in order
/// from the camera side (one-sided limits at jumps come from the piece).
template <class F>
void for_each_ramp_piece(const Classifier& tf, double vf, double vb, F&& f) {
    const auto& sig = tf.sigma_function();
    const auto& col = tf.color_function();
    auto piece = [&](double l0, double l1) {
        const double v0 = vf + l0 * (vb - vf), v1 = vf + l1 * (vb - vf);
        const double vm = 0.5 * (v0 + v1);
        const std::size_t ps = sig.piece(vm), pc = col.piece(vm);
        const double s0 = sig.on_piece(ps, v0)[0], s1 = sig.on_piece(ps, v1)[0];
        const Rgb c0 = col.on_piece(pc, v0), c1 = col.on_piece(pc, v1);
        f(RampPiece{
            l1 - l0, s0, s1,
            tf.associated() ? preint::emission_source(c0, c1) : preint::particle_source(s0, s1, c0, c1)});
    };
    const auto& knots = tf.breakpoints();
    double l = 0.0;
    if (vf < vb) {
        for (auto it = std::upper_bound(knots.begin(), knots.end(), vf); it != knots.end() && *it < vb;
             ++it) {
            const double ln = (*it - vf) / (vb - vf);
            piece(l, ln);
            l = ln;
        }
    } else if (vb < vf) {
        auto it = std::lower_bound(knots.begin(), knots.end(), vf);
        while (it != knots.begin() && *(it - 1) > vb) {
            --it;
            const double ln = (vf - *it) / (vf - vb);
            piece(l, ln);
            l = ln;
        }
    }
    piece(l, 1.0);
}

/// Composes ramp pieces along one segment of length δ under model M:
/// eq. (16) (later pieces attenuated by earlier ones) or eq. (17) (not).
template <Model M>
class RampIntegral {
public:
    RampIntegral(double delta, bool full) : delta_(delta), full_(full) {}
    // By reference: a copy of the piece (stored a double at a time, reloaded
    // 16 bytes at a time) stalled on store forwarding.
    void add(const RampPiece& p) {
        static constexpr preint::Quadratic kNoSource{};
        const bool absorb = M != Model::emission;
        const auto r = preint::integrate_piece(p.dl * delta_, absorb ? p.s0 : 0.0, absorb ? p.s1 : 0.0,
                                               M == Model::absorption ? kNoSource : p.g, full_);
        for (int k = 0; k < 3; ++k) E_[k] += (full_ ? T_ : 1.0) * r.radiance[k];
        depth_ += r.depth;
        T_ = preint::exp_neg(depth_);
    }
    [[nodiscard]] Segment result() const { return {T_, E_}; }

private:
    double delta_;
    bool full_;
    Rgb E_{0, 0, 0};
    double depth_ = 0.0, T_ = 1.0;
};

namespace preint {
/// Without self-attenuation a segment is a difference of integral functions
/// (eqs. (15), (17)) where |v_b − v_f| exceeds this fraction of
/// |v_f − K₀| + |v_b − K₀| (K₀ the first breakpoint, where S and G are 0):
/// S and G are then at most a few ulp of σ_max·that sum off, so τ and the
/// radiance are within about 1e−8·δ·σ_max (g_max) of the exact integrals.
/// Flatter ramps, v_b = v_f among them, take the pieces.
inline constexpr double kFlatRamp = 0x1p-24;

inline bool steep_ramp(const IntegralFunctions& f, double vf, double vb) {
    if (f.empty()) return false;
    const double k0 = f.knots.front();
    return std::abs(vb - vf) > kFlatRamp * (std::abs(vf - k0) + std::abs(vb - k0));  // false for NaN
}

/// preintegrated-simple's segment from the integral functions (eqs. (15),
/// (17)): τ = δ·(S(v_b) − S(v_f))/(v_b − v_f), C = δ·(G(v_b) − G(v_f))/(v_b − v_f);
/// for a steep_ramp. simd_preint.cpp's lanes perform the same operations.
template <Model M>
Segment integral_segment(const IntegralFunctions& f, double vf, double vb, double delta) {
    const double r = delta / (vb - vf);
    const std::size_t pf = f.row(vf), pb = f.row(vb);
    Segment s{1.0, {0.0, 0.0, 0.0}};
    if constexpr (M != Model::emission) {
        const double tau = (f.S(pb, vb) - f.S(pf, vf)) * r;
        s.transmittance = exp_neg(tau > 0.0 ? tau : 0.0);  // rounding may leave −0 or a tiny negative
    }
    if constexpr (M != Model::absorption) {
        const Rgb gf = f.G(pf, vf), gb = f.G(pb, vb);
        for (std::size_t k = 0; k < 3; ++k) s.radiance[k] = (gb[k] - gf[k]) * r + 0.0;  // + 0: no −0
    }
    return s;
}
}  // namespace preint

/// One pre-integrated segment of a scalar volume: the ramp from v_front
/// (camera side) to v_back over length δ, under model M (eqs. (15)–(17)).
template <Model M>
Segment preintegrate_scalar(const Classifier& tf, double vf, double vb, double delta, bool full) {
    // Where the medium is zero over the whole ramp the integrals below give
    // exactly (1, 0): return that at once (the same bits, much sooner).
    if (medium_zero_on(tf, M, std::min(vf, vb), std::max(vf, vb))) return {1.0, {0.0, 0.0, 0.0}};
    if (!full && preint::steep_ramp(tf.integrals(), vf, vb))
        return preint::integral_segment<M>(tf.integrals(), vf, vb, delta);
    RampIntegral<M> acc(delta, full);
    for_each_ramp_piece(tf, vf, vb, [&](const RampPiece& p) { acc.add(p); });
    return acc.result();
}

/// One pre-integrated segment of pre-classified grids: σ and c linear
/// between the end samples.
template <Model M>
Segment preintegrate_grid(double sf, const Rgb& cf, double sb, const Rgb& cb, double delta, bool full) {
    preint::Quadratic g = preint::particle_source(sf, sb, cf, cb);
    if constexpr (M == Model::absorption) g = {};
    if constexpr (M == Model::emission) sf = sb = 0.0;
    const auto r = preint::integrate_piece(delta, sf, sb, g, full);
    return {preint::exp_neg(r.depth), r.radiance};
}

namespace detail {
/// integrate_preintegrated below; kPacked: full pre-integration of an
/// unshaded scalar medium with `simd`, whose windows' segments are packed.
template <Model M, bool kPacked, class Medium>
RayResult preintegrated_ray(const Medium& medium, const RaySpan& span, const RenderSettings& s, double h,
                            const Rgb& bg, bool full, const EmptySpace* es, const simd::BatchSource* simd) {
    const std::int64_t n = segment_count(span.length(), h);
    const double delta = span.length() / static_cast<double>(n);
    const SampleGrid grid{&span, delta, 0.0, 0};  // end j at t_near + j·δ
    using End = decltype(medium.end_sample(Vec3{}));
    std::array<std::int64_t, 2> idx{-1, -1};
    std::array<End, 2> val{};
    int older = 0;
    // SIMD: the ends `win` holds in `batch`; run_end is the last end the
    // evaluated run needs (set by the skipping walk).
    const simd::RayGrid rg{span.p0, span.dp, span.t_near, delta, 0.0, 0};
    // The window's ends (batch[l]: end win.b0 + l): up to kBatch
    // interpolated at store + kCarry, 64-byte aligned, and where the window
    // goes on from the last one, that one's last end carried over beside
    // them (the same bits: the same end), so that a window of kBatch + 1
    // ends gives kBatch segments (whole vectors) and no end is interpolated
    // twice. Packed (below), a window that goes on from the last takes up
    // to kWide ends.
    constexpr int kCarry = 8;
    constexpr int kWide = 3 * simd::kBatch;
    alignas(64) double store[kCarry + (kPacked ? kWide : simd::kBatch) + 8] = {};  // read past the last end
    const double* batch = store + kCarry;
    simd::Window win;
    // The segments between the window's ends, computed on the first request.
    simd::SegmentBatch segs;
    bool segs_ready = false;
    // Packed (full pre-integration, unshaded): the window's wanted segments
    // (not both ends below the zero range) are pre-integrated kPackChunk at
    // a time, from the first one requested on in the order of travel,
    // packed into whole vectors across the window's gaps (preintegrate_pack:
    // the same bits); slot[l]: segment l's place in `pack`, −1 until then.
    constexpr int kPackChunk = simd::kBatch;
    simd::SegmentPack pack;                    // (unused unless kPacked)
    std::array<std::int16_t, kWide + 1> slot;  // set by load_window
    // Shaded media: the shading factors at the midpoints of those segments
    // (segment i at t_near + (i − 0.5)·δ), computed on the first request.
    simd::RayGrid mid{span.p0, span.dp, span.t_near, delta, -0.5, 0};
    if constexpr (Medium::kShaded) mid.view = medium.view;
    simd::ShadeBatch shades;
    bool shades_ready = false;
    std::int64_t run_end = s.order == Order::front_to_back ? n : 0;
    std::uint64_t below = 0;  // bit l: end win.b0 + l is below simd->zero_below
    bool masked = false;      // whether `below` holds the window's bits
    // The batch of ends from j in the direction of travel; with `mask`, also
    // which of them lie below the medium's zero range (the skipping walk's).
    auto load_window = [&](std::int64_t j, bool mask) {
        const bool forward = s.order == Order::front_to_back;
        // the last window's end at j, carried over (its bits too where the new ones are needed)
        const bool carry = (forward ? win.b1 == j : win.b0 == j) && (masked || !mask);
        const double carried = carry ? batch[j - win.b0] : 0.0;
        const std::uint64_t carried_bit = carry && mask ? (below >> (j - win.b0)) & 1u : 0u;
        double* fresh = store + kCarry;
        std::uint64_t bits = 0;
        // with a carried end, kBatch (packed: kWide) new ones beside it
        // (after it forward, before it backward)
        win.start_at(j, forward, run_end, carry ? (kPacked ? kWide : simd::kBatch) + 1 : simd::kBatch);
        const int k = carry ? win.count() - 1 : win.count();
        const std::int64_t j0 = carry && forward ? win.b0 + 1 : win.b0;
        if (k > 0) simd::interpolate_batch(*simd, rg, j0, k, fresh, mask ? &bits : nullptr);
        batch = fresh;
        if (carry && forward) {  // ends j (carried), j + 1 … win.b1
            store[kCarry - 1] = carried;
            batch = store + kCarry - 1;
            bits = bits << 1 | carried_bit;
        } else if (carry) {  // ends win.b0 … j − 1, j (carried)
            fresh[k] = carried;
            bits |= carried_bit << k;
        }
        below = bits;
        masked = mask;
        segs_ready = false;
        shades_ready = false;
        if constexpr (kPacked) {
            pack.count = 0;
            std::fill(slot.begin(), slot.end(), std::int16_t{-1});
        }
    };
    auto end = [&](std::int64_t j) -> End {
        if constexpr (Medium::kHasScalar) {
            if (simd != nullptr) {
                if (!win.holds(j)) load_window(j, false);
                return batch[j - win.b0];
            }
        }
        if (idx[0] == j) return val[0];
        if (idx[1] == j) return val[1];
        const int slot = older;
        older ^= 1;
        idx[slot] = j;
        val[slot] = medium.end_sample(grid.at(j));
        return val[slot];
    };
    // Shading with the gradient at the segment's midpoint (shade_segment).
    auto shaded = [full](const Segment& seg, const auto& sf) { return shade_segment(seg, sf, full); };
    auto segment = [&](std::int64_t i) {
        const End f = end(i - 1), b = end(i);
        if constexpr (Medium::kShaded) {
            const Segment seg = preintegrate_scalar<M>(*medium.tf, f, b, delta, full);
            if (seg.transmittance == 1.0 && seg.radiance == Rgb{0, 0, 0}) return seg;  // nothing to shade
            return shaded(seg, medium.factors(span.at(span.t_near + (static_cast<double>(i) - 0.5) * delta)));
        } else if constexpr (Medium::kHasScalar) {
            return preintegrate_scalar<M>(*medium.tf, f, b, delta, full);
        } else {
            return preintegrate_grid<M>(f.sigma, f.color, b.sigma, b.color, delta, full);
        }
    };
    DepthTrack depth{span.t_near, delta};
    DepthTrack* track = s.depth_outputs ? &depth : nullptr;
    // Segments whose two ends lie in one box of empty macrocells are (1, 0);
    // those with an end in a non-empty one are evaluated without further
    // lookups.
    // Where empty macrocells join (EmptySpace::joins_empty), ends in
    // different boxes of them bound empty segments too.
    const std::optional<RunFinder> runs =
        es != nullptr ? std::optional<RunFinder>(std::in_place, *es, grid) : std::nullopt;
    const bool joins = es != nullptr && es->joins_empty();
    auto find = [&](std::int64_t j, int dir, std::int64_t limit) {
        return joins ? runs->run_through(j, dir, limit) : runs->run(j, dir, limit);
    };
    // The next run of segments from i: k > 0 to skip, −k to evaluate
    // (composite's convention); sets run_end, the last end it needs.
    auto next_run = [&](std::int64_t i, int dir) -> std::int64_t {
        if (dir > 0) {  // front ends i−1..k share a box (or join)
            const auto run = find(i - 1, +1, n);
            if (run.empty && run.last >= i) return run.last - i + 1;             // segments i..k
            const std::int64_t m = std::max<std::int64_t>(1, run.last - i + 2);  // segments i..k+1
            run_end = i + m - 1;
            return -m;
        }
        const auto run = find(i, -1, 0);                     // back ends k..i share a box (or join)
        if (run.empty && run.last < i) return i - run.last;  // segments k+1..i
        const std::int64_t m = std::max<std::int64_t>(1, i - run.last + 1);  // segments k..i
        run_end = i - m;
        return -m;
    };
    if constexpr (Medium::kHasScalar) {
        if (simd != nullptr) {
            // With SIMD, an evaluated run (kLeastRun segments at least) is
            // split by its batch of ends: a segment whose two ends both lie
            // below the medium's zero range has a ramp in that range, so it
            // is (1, 0): skipped too. Without skipping, the whole ray is one
            // run.
            // The evaluated run's last segment, and whether i lies in it.
            std::int64_t seg_end = s.order == Order::front_to_back ? n : 1;
            bool in_run = es == nullptr;
            // Packed: the next kPackChunk wanted segments of the window from
            // segment l on (in the order of travel), in a new vector. (Not
            // inlined: the segments' hot path stays small.)
            auto pack_from = [&](int l) __attribute__((noinline)) {
                const std::uint64_t skip = below & (below >> 1);
                const int step = s.order == Order::front_to_back ? 1 : -1, last = win.count() - 2;
                const int first = (pack.count + 7) / 8 * 8;
                pack.count = first;
                for (int q = l; q >= 0 && q <= last && pack.count - first < kPackChunk; q += step) {
                    const auto u = static_cast<std::size_t>(q);
                    if (((skip >> q) & 1u) != 0 || slot[u] >= 0) continue;
                    slot[u] = static_cast<std::int16_t>(pack.count);
                    pack.vf[pack.count] = batch[q];
                    pack.vb[pack.count] = batch[q + 1];
                    pack.delta[pack.count] = delta;
                    ++pack.count;
                }
                simd::preintegrate_pack(*simd, M, full, pack, first);
            };
            // The run splitter below has loaded a window holding both ends.
            auto batch_segment = [&](std::int64_t i) -> Segment {
                if constexpr (kPacked) {
                    const auto l = static_cast<std::size_t>(i - 1 - win.b0);
                    if (slot[l] < 0) pack_from(static_cast<int>(l));
                    const auto k = static_cast<std::size_t>(slot[l]);
                    if (pack.scalar[k] != 0.0) return segment(i);
                    return {pack.transmittance[k],
                            {pack.radiance[0][k], pack.radiance[1][k], pack.radiance[2][k]}};
                }
                if (!segs_ready) {  // all but the segments with both ends below the zero range
                    simd::preintegrate_batch(*simd, M, full, delta, batch, win.count(),
                                             static_cast<std::uint32_t>(below & (below >> 1)), segs);
                    segs_ready = true;
                }
                const auto l = static_cast<std::size_t>(i - 1 - win.b0);
                if constexpr (Medium::kShaded) {
                    if (((segs.scalar >> l) & 1u) != 0) return segment(i);
                    const Segment seg{segs.transmittance[l],
                                      {segs.radiance[0][l], segs.radiance[1][l], segs.radiance[2][l]}};
                    if (seg.transmittance == 1.0 && seg.radiance == Rgb{0, 0, 0}) return seg;
                    if (simd->shade == nullptr)  // precomputed gradients
                        return shaded(seg, medium.factors(span.at(span.t_near +
                                                                  (static_cast<double>(i) - 0.5) * delta)));
                    if (!shades_ready) {  // the window's segments, but those with both ends below the zero
                                          // range
                        simd::shade_batch(*simd, mid, win.b0 + 1, win.count() - 1,
                                          static_cast<std::uint32_t>(below & (below >> 1)), shades);
                        shades_ready = true;
                    }
                    decltype(medium.factors(Vec3{})) sf;
                    for (int c = 0; c < 3; ++c) {
                        sf.diffuse[c] = shades.diffuse[c][l];
                        sf.specular[c] = shades.specular[c][l];
                    }
                    sf.opacity = shades.opacity[l];
                    return shaded(seg, sf);
                }
                if (((segs.scalar >> l) & 1u) != 0) return segment(i);
                return {segs.transmittance[l],
                        {segs.radiance[0][l], segs.radiance[1][l], segs.radiance[2][l]}};
            };
            return composite(
                n, s.order, s.termination, bg, batch_segment,
                [&](std::int64_t i, int dir) -> std::int64_t {
                    if (!in_run || dir * (seg_end - i) < 0) {
                        const std::int64_t k = next_run(i, dir);
                        if (k > 0) return k;
                        seg_end = simd::least_run_end(i, dir, i + dir * (-k - 1), dir > 0 ? n : 1);
                        run_end = dir > 0 ? seg_end : seg_end - 1;  // its last end
                        in_run = true;
                    }
                    if (!win.holds(i - 1) || !win.holds(i))
                        load_window(dir > 0 ? i - 1 : i, true);  // ends i − 1, i
                    // bit p: segment win.b0 + p + 1 (ends p, p + 1) is zero
                    return simd::split_zero(
                        below & (below >> 1), i - 1 - win.b0, dir,
                        dir > 0 ? std::min(win.b1, seg_end) - i + 1 : i - std::max(win.b0 + 1, seg_end) + 1);
                },
                track);
        }
    }
    if (es == nullptr) return composite(n, s.order, s.termination, bg, segment, NoSkip{}, track);
    return composite(n, s.order, s.termination, bg, segment, next_run, track);
}
}  // namespace detail

/// The integrator: samples the n + 1 segment ends once each and composites
/// the segments. The scalar of a scalar medium is interpolated kBatch ends
/// at a time with `simd`, and (unshaded) the segments between them are
/// pre-integrated a vector at a time (simd_preint.h; the same bits; with
/// self-attenuation, a window's wanted segments packed into whole vectors,
/// an instantiation of its own, so that the other paths keep their smaller
/// frame); otherwise a two-slot cache serves both orders. With `es`, runs
/// of segments whose two ends lie in one box of empty macrocells are
/// skipped (exact).
template <Model M, class Medium>
RayResult integrate_preintegrated(const Medium& medium, const RaySpan& span, const RenderSettings& s,
                                  double h, const Rgb& bg, bool full, const EmptySpace* es,
                                  const simd::BatchSource* simd = nullptr) {
    if constexpr (Medium::kHasScalar && !Medium::kShaded)
        if (simd != nullptr && full)
            return detail::preintegrated_ray<M, true>(medium, span, s, h, bg, full, es, simd);
    return detail::preintegrated_ray<M, false>(medium, span, s, h, bg, full, es, simd);
}

}  // namespace fathom
