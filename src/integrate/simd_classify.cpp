// Highway's foreach_target: this file is compiled once per x86 target and
// classify_batch dispatches at run time (src/integrate/simd_classify.h).
#include "integrate/simd_classify.h"

#include <algorithm>
#include <array>
#include <atomic>
#include <bit>
#include <cstdint>
#include <limits>
#include <type_traits>

#include "core/parallel.h"
#include "integrate/point_rules.h"
#include "integrate/simd_preint.h"
#include "render/empty_space.h"
#include "render/shading.h"
#include "volume/bricks.h"

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "integrate/simd_classify.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

#include "integrate/exp_neg-inl.h"
#include "integrate/gather-inl.h"

HWY_BEFORE_NAMESPACE();
namespace fathom::simd {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<double>;
using V = hn::Vec<D>;
using M = hn::Mask<D>;

/// Where v lies on a function of at most FlatFunction::kTable knots (and at
/// most a vector's lanes): the knots i − 1 and i around it (i = the number
/// of knots ≤ v), its position w on that piece, and whether it lies past
/// the first and before the last knot.
struct KnotPiece {
    using Idx = decltype(hn::IndicesFromVec(D(), hn::Zero(hn::RebindToSigned<D>())));
    Idx lo, hi;
    V w;
    M any_below, any_above;
    KnotPiece(D d, const FlatFunction& f, V v) {
        const hn::RebindToSigned<D> di;
        const std::size_t n = f.knots.size();
        const auto i = exp_v::CountKeys<false>(d, f.knots.data(), n, v);
        lo = hn::IndicesFromVec(d, hn::Max(hn::Sub(i, hn::Set(di, 1)), hn::Zero(di)));
        hi = hn::IndicesFromVec(d, hn::Min(i, hn::Set(di, static_cast<std::int64_t>(n - 1))));
        const V below = hn::TableLookupLanes(hn::LoadU(d, f.table[0]), lo);
        w = exp_v::PiecePosition(v, below,
                                 hn::TableLookupLanes(hn::LoadU(d, f.table[FlatFunction::kInvRow]), lo));
        any_below = hn::RebindMask(d, hn::Gt(i, hn::Zero(di)));
        any_above = hn::RebindMask(d, hn::Lt(i, hn::Set(di, static_cast<std::int64_t>(n))));
    }
};

/// f's components on the piece p (knots i − 1 and i by lane permutation:
/// the same operands as eval's loops below).
HWY_INLINE void on_knot_piece(D d, const FlatFunction& f, const KnotPiece& p, V* out) {
    const std::size_t n = f.knots.size();
    for (int c = 0; c < f.components; ++c) {
        const V y = hn::LoadU(d, f.table[1 + c]);
        const V y0 = hn::TableLookupLanes(y, p.lo), y1 = hn::TableLookupLanes(y, p.hi);
        const V r = exp_v::Fma(p.w, hn::Sub(y1, y0), y0);
        out[c] = hn::IfThenElse(p.any_below, hn::IfThenElse(p.any_above, r, hn::Set(d, f.y[c][n - 1])),
                                hn::Set(d, f.y[c][0]));
    }
}

/// Whether σ and c share their knots, few enough for KnotPiece: one then
/// serves both.
inline bool shared_pieces(const BatchSource& src) {
    const std::size_t n = src.sigma->knots.size();
    return n > 1 && n <= FlatFunction::kTable && n <= hn::Lanes(D()) && src.shared_knots;
}

/// f(v) per lane for each component, as PiecewiseLinear::on_piece(piece(v),
/// v) computes it: the same operations in the same order.
HWY_INLINE void eval(D d, const FlatFunction& f, V v, V* out) {
    const auto& kn = f.knots;
    const std::size_t n = kn.size();
    const int nc = f.components;
    if (n == 1) {
        for (int c = 0; c < nc; ++c) out[c] = hn::Set(d, f.y[c][0]);
        return;
    }
    if (n <= FlatFunction::kTable && n <= hn::Lanes(d)) {
        on_knot_piece(d, f, KnotPiece(d, f, v), out);
        return;
    }
    V below = hn::Set(d, kn[0]), inv = hn::Set(d, f.inv[0]);
    V y0[3], y1[3];
    for (int c = 0; c < nc; ++c) {
        y0[c] = hn::Set(d, f.y[c][0]);
        y1[c] = hn::Set(d, f.y[c][n - 1]);
    }
    auto any_below = hn::Le(hn::Set(d, kn[0]), v);
    for (std::size_t i = 1; i < n; ++i) {  // the last knot ≤ v
        const auto m = hn::Le(hn::Set(d, kn[i]), v);
        below = hn::IfThenElse(m, hn::Set(d, kn[i]), below);
        inv = hn::IfThenElse(m, hn::Set(d, f.inv[i]), inv);
        for (int c = 0; c < nc; ++c) y0[c] = hn::IfThenElse(m, hn::Set(d, f.y[c][i]), y0[c]);
    }
    auto any_above = hn::Lt(v, hn::Set(d, kn[n - 1]));
    for (std::size_t i = n - 1; i-- > 0;) {  // the first knot > v
        const auto m = hn::Lt(v, hn::Set(d, kn[i]));
        for (int c = 0; c < nc; ++c) y1[c] = hn::IfThenElse(m, hn::Set(d, f.y[c][i]), y1[c]);
    }
    if (n > 8) {  // PiecewiseLinear::piece bisects beyond 8 knots: NaN lands after the last
        const auto nan = hn::IsNaN(v);
        any_below = hn::Or(any_below, nan);
        any_above = hn::AndNot(nan, any_above);
    }
    const V w = exp_v::PiecePosition(v, below, inv);
    for (int c = 0; c < nc; ++c) {
        const V r = exp_v::Fma(w, hn::Sub(y1[c], y0[c]), y0[c]);
        // p = 0: the first value; p = n: the last
        out[c] = hn::IfThenElse(any_below, hn::IfThenElse(any_above, r, hn::Set(d, f.y[c][n - 1])),
                                hn::Set(d, f.y[c][0]));
    }
}

/// The pair (q[0], q[1]) at byte offsets `o` (int32 lanes) of 8- and 16-bit
/// samples, as int32 lanes. 8-bit reads that would pass the array's last
/// word `last` are moved back and the word shifted.
template <class T, class DI, class VI>
HWY_INLINE void gather_pair(DI di, const BatchSource& src, VI o, VI last, VI& lo, VI& hi) {
    const hn::Rebind<std::uint32_t, DI> du;
    const auto* words = reinterpret_cast<const std::int32_t*>(src.data);
    hn::Vec<decltype(du)> w;
    if constexpr (sizeof(T) == 1) {
        const auto o4 = hn::Min(o, last);
        w = hn::BitCast(du, gather::Words(di, words, o4));
        w = hn::operator>>(w, hn::BitCast(du, hn::ShiftLeft<3>(hn::Sub(o, o4))));
    } else {
        w = hn::BitCast(du, gather::Words(di, words, o));
    }
    const auto wi = hn::BitCast(di, w);
    if constexpr (std::is_same_v<T, std::uint8_t>) {
        lo = hn::BitCast(di, hn::And(w, hn::Set(du, 0xFFu)));
        hi = hn::BitCast(di, hn::And(hn::ShiftRight<8>(w), hn::Set(du, 0xFFu)));
    } else if constexpr (std::is_same_v<T, std::int8_t>) {  // sign-extended bytes
        lo = hn::ShiftRight<24>(hn::ShiftLeft<24>(wi));
        hi = hn::ShiftRight<24>(hn::ShiftLeft<16>(wi));
    } else if constexpr (std::is_same_v<T, std::uint16_t>) {
        lo = hn::BitCast(di, hn::And(w, hn::Set(du, 0xFFFFu)));
        hi = hn::BitCast(di, hn::ShiftRight<16>(w));
    } else {  // int16: sign-extended halves
        lo = hn::ShiftRight<16>(hn::ShiftLeft<16>(wi));
        hi = hn::ShiftRight<16>(wi);
    }
}

/// The x-fastest node index i + nx·(j + ny·k) of lanes b … b + N − 1 of the
/// cells, in doubles (exact: an integer below 2⁵³).
HWY_INLINE V linear_node(D d, const BatchSource& src, const double (*cell)[kBatch], std::size_t b) {
    return hn::Add(hn::Load(d, cell[0] + b),
                   hn::Mul(hn::Set(d, static_cast<double>(src.nx)),
                           hn::Add(hn::Load(d, cell[1] + b), hn::Mul(hn::Set(d, static_cast<double>(src.ny)),
                                                                     hn::Load(d, cell[2] + b)))));
}

/// The nodes a brick of the last slab along z stores, and those of a slab
/// of whole bricks (Bricks::cell_index).
inline std::int64_t last_brick_nodes(const BatchSource& src) {
    return Bricks::last_brick_nodes(src.nz);
}
inline std::int64_t slab_nodes(const BatchSource& src) {
    return src.bricks_x * src.bricks_y * Bricks::kBrickNodes;
}

/// Bricks::cell_index of lanes b … b + N − 1 of the cells, in doubles
/// (exact: every term is an integer below 2³¹).
HWY_INLINE V brick_node(D d, const BatchSource& src, const double (*cell)[kBatch], std::size_t b) {
    const V per = hn::Set(d, 1.0 / static_cast<double>(Bricks::kCells)),
            edge = hn::Set(d, static_cast<double>(Bricks::kCells));
    V brick[3], local[3];
    for (int a = 0; a < 3; ++a) {
        const V c = hn::Load(d, cell[a] + b);
        brick[a] = hn::Floor(hn::Mul(c, per));  // kCells is a power of two: exact
        local[a] = hn::Sub(c, hn::Mul(brick[a], edge));
    }
    const V nodes = hn::Set(d, static_cast<double>(Bricks::kNodes));
    const V in_slab = hn::Add(brick[0], hn::Mul(hn::Set(d, static_cast<double>(src.bricks_x)), brick[1]));
    const V brick_nodes = hn::IfThenElse(hn::Eq(brick[2], hn::Set(d, static_cast<double>(src.bricks_z - 1))),
                                         hn::Set(d, static_cast<double>(last_brick_nodes(src))),
                                         hn::Set(d, static_cast<double>(Bricks::kBrickNodes)));
    const V within = hn::Add(local[0], hn::Mul(nodes, hn::Add(local[1], hn::Mul(nodes, local[2]))));
    return hn::Add(hn::Add(hn::Mul(brick[2], hn::Set(d, static_cast<double>(slab_nodes(src)))),
                           hn::Mul(in_slab, brick_nodes)),
                   within);
}

/// GridSampler::interpolate of the corners c[0..7] ((0,0,0), (1,0,0),
/// (0,1,0), (1,1,0), (0,0,1), … in x-fastest order) at fractions (fx, fy, fz).
/// Each lerp a + f·(b − a), fused or not, stays within [a, b] where the
/// scalar one does (empty_space.cpp's sample_range).
HWY_INLINE V Lerp8(const V* c, V fx, V fy, V fz) {
    using exp_v::Fma;
    const V c00 = Fma(fx, hn::Sub(c[1], c[0]), c[0]);
    const V c10 = Fma(fx, hn::Sub(c[3], c[2]), c[2]);
    const V c01 = Fma(fx, hn::Sub(c[5], c[4]), c[4]);
    const V c11 = Fma(fx, hn::Sub(c[7], c[6]), c[6]);
    const V c0 = Fma(fy, hn::Sub(c10, c00), c00);
    const V c1 = Fma(fy, hn::Sub(c11, c01), c01);
    return Fma(fz, hn::Sub(c1, c0), c0);
}

/// The samples stored, x-fastest or in bricks (their aprons included).
inline std::int64_t stored_nodes(const BatchSource& src) {
    return src.bricks_x > 0 ? Bricks::nodes_for({src.nx, src.ny, src.nz}) : src.nx * src.ny * src.nz;
}

/// Nodes i and i + 1 of a row per lane, at byte offsets `o` of the first
/// (exact integers), x-fastest or in a brick: 8- and 16-bit samples from a
/// 32-bit gather (offsets below 2³¹), float32 from a 64-bit one; as doubles.
template <class T>
HWY_INLINE void gather_x_pair(D d, const BatchSource& src, V o, V* v) {
    if constexpr (std::is_same_v<T, float>) {
        const hn::Rebind<std::int64_t, D> dl;
        const hn::Rebind<std::uint64_t, D> dq;
        const hn::Rebind<std::uint32_t, D> du;
        const hn::Rebind<float, D> df;
        const auto w = gather::Words(dq, static_cast<const std::uint64_t*>(src.data), hn::ConvertTo(dl, o));
        v[0] = hn::PromoteTo(d, hn::BitCast(df, hn::TruncateTo(du, w)));
        v[1] = hn::PromoteTo(d, hn::BitCast(df, hn::TruncateTo(du, hn::ShiftRight<32>(w))));
    } else {
        const hn::Rebind<std::int32_t, D> di;
        const auto last = hn::Set(
            di, static_cast<std::int32_t>(stored_nodes(src) * static_cast<std::int64_t>(sizeof(T)) - 4));
        hn::Vec<decltype(di)> l, u;
        gather_pair<T>(di, src, hn::DemoteTo(di, o), last, l, u);
        v[0] = hn::PromoteTo(d, l);
        v[1] = hn::PromoteTo(d, u);
    }
}

/// The byte offsets of a cell's four corner rows from its first node: in a
/// brick, kNodes and kNodes² nodes apart.
template <class T>
HWY_INLINE std::array<std::int64_t, 4> corner_rows(const BatchSource& src) {
    const bool bricked = src.bricks_x > 0;
    const std::int64_t sy = (bricked ? Bricks::kNodes : src.nx) * static_cast<std::int64_t>(sizeof(T)),
                       sz = sy * (bricked ? Bricks::kNodes : src.ny);
    return {0, sy, sz, sz + sy};
}

/// The byte offset of the first node of the cells of lanes b … b + N − 1,
/// x-fastest or in bricks: an exact integer in doubles. For float32
/// samples, whose x-fastest offsets may pass 2³¹ (their 64-bit gathers
/// take 64-bit offsets); the narrower types take cell_offsets.
template <class T>
HWY_INLINE V cell_bytes(D d, const BatchSource& src, const double (*cell)[kBatch], std::size_t b) {
    return hn::Mul(src.bricks_x > 0 ? brick_node(d, src, cell, b) : linear_node(d, src, cell, b),
                   hn::Set(d, static_cast<double>(sizeof(T))));
}

/// cell_bytes in 32-bit integers (where the offsets of every stored node
/// fit, as the paired gathers need): the same offsets, from shifts and
/// integer products instead of a chain of double operations.
template <class T, class DI>
HWY_INLINE hn::Vec<DI> cell_offsets(DI di, const BatchSource& src, const double (*cell)[kBatch],
                                    std::size_t b) {
    const D d;
    hn::Vec<DI> c[3];
    for (int a = 0; a < 3; ++a) c[a] = hn::DemoteTo(di, hn::Load(d, cell[a] + b));
    auto set = [&](std::int64_t v) { return hn::Set(di, static_cast<std::int32_t>(v)); };
    constexpr std::int64_t size = sizeof(T);
    if (src.bricks_x <= 0)
        return hn::Mul(hn::Add(c[0], hn::Mul(set(src.nx), hn::Add(c[1], hn::Mul(set(src.ny), c[2])))),
                       set(size));
    static_assert(Bricks::kCells == 32);
    const auto mask = set(Bricks::kCells - 1);
    const auto bz = hn::ShiftRight<5>(c[2]);
    const auto in_slab =
        hn::Add(hn::ShiftRight<5>(c[0]), hn::Mul(set(src.bricks_x), hn::ShiftRight<5>(c[1])));
    // the last slab's bricks hold fewer planes (Bricks::cell_index)
    const auto brick_bytes =
        hn::IfThenElse(hn::Eq(bz, set(src.bricks_z - 1)), set(last_brick_nodes(src) * size),
                       set(Bricks::kBrickNodes * size));
    const auto within =
        hn::Add(hn::And(c[0], mask),
                hn::Mul(set(Bricks::kNodes),
                        hn::Add(hn::And(c[1], mask), hn::Mul(set(Bricks::kNodes), hn::And(c[2], mask)))));
    return hn::Add(hn::Add(hn::Mul(bz, set(slab_nodes(src) * size)), hn::Mul(in_slab, brick_bytes)),
                   hn::Mul(within, set(size)));
}

/// GridSampler::interpolate of vectors of cells and fractions, the corners
/// gathered in pairs (q[0], q[1]) per row: the same values, the same
/// operations, so the same bits as the scalar fetch.
template <class T>
HWY_INLINE void pair_corners(const BatchSource& src, const double (*cell)[kBatch],
                             const double (*frac)[kBatch], std::size_t b0, std::size_t b1, double* out,
                             bool skip_inactive) {
    const D d;
    const std::size_t N = hn::Lanes(d);
    constexpr std::int64_t size = sizeof(T);
    const std::array<std::int64_t, 4> rows = corner_rows<T>(src);
    const std::int64_t stored = stored_nodes(src);
    const V bx = hn::Set(d, static_cast<double>(src.nx / 2)),
            by = hn::Set(d, static_cast<double>(src.ny / 2));
    for (std::size_t b = b0; b < b1; b += N) {
        if (skip_inactive) {  // no block with a node at or above zero_below: every value is below it
            const hn::Rebind<std::int32_t, D> di;
            const V half = hn::Set(d, 0.5);
            auto block = [&](int a) { return hn::Floor(hn::Mul(hn::Load(d, cell[a] + b), half)); };
            const V blocks = hn::Add(block(0), hn::Mul(bx, hn::Add(block(1), hn::Mul(by, block(2)))));
            const auto ni = hn::DemoteTo(di, blocks);
            const auto word = gather::Words(di, reinterpret_cast<const std::int32_t*>(src.active),
                                            hn::ShiftLeft<2>(hn::ShiftRight<5>(ni)));
            const auto bit = hn::And(hn::Shr(word, hn::And(ni, hn::Set(di, 31))), hn::Set(di, 1));
            if (hn::AllTrue(di, hn::Eq(bit, hn::Zero(di)))) {
                hn::Store(hn::Set(d, -INFINITY), d, out + b);
                continue;
            }
        }
        V c[8];
        if constexpr (std::is_same_v<T, float>) {  // 64 bits: two floats per gather
            const V bytes = cell_bytes<T>(d, src, cell, b);
            for (int r = 0; r < 4; ++r)
                gather_x_pair<T>(d, src, hn::Add(bytes, hn::Set(d, static_cast<double>(rows[r]))), c + 2 * r);
        } else {  // gather_x_pair's, the offset computed once for the 4 rows
            const hn::Rebind<std::int32_t, D> di;
            const auto off = cell_offsets<T>(di, src, cell, b);
            const auto last = hn::Set(di, static_cast<std::int32_t>(stored * size - 4));
            for (int r = 0; r < 4; ++r) {
                hn::Vec<decltype(di)> lo, hi;
                gather_pair<T>(di, src, hn::Add(off, hn::Set(di, static_cast<std::int32_t>(rows[r]))), last,
                               lo, hi);
                c[2 * r] = hn::PromoteTo(d, lo);
                c[2 * r + 1] = hn::PromoteTo(d, hi);
            }
        }
        hn::Store(Lerp8(c, hn::Load(d, frac[0] + b), hn::Load(d, frac[1] + b), hn::Load(d, frac[2] + b)), d,
                  out + b);
    }
}

/// Nodes i, i + 1 and i + 2 of a row at byte offsets `o` of the first, as
/// doubles: 8- and 16-bit samples from one gather per lane (the 16-bit ones
/// from 64-bit words; reads that would pass the array's end are moved back
/// and the word shifted), float32 from two pairs (i, i + 1) and (i + 1,
/// i + 2).
template <class T>
HWY_INLINE void gather_triple(D d, const BatchSource& src, V o, V* v) {
    const std::int64_t bytes = src.nx * src.ny * src.nz * static_cast<std::int64_t>(sizeof(T));
    if constexpr (std::is_same_v<T, float>) {
        V upper[2];
        gather_x_pair<T>(d, src, o, v);
        gather_x_pair<T>(d, src, hn::Add(o, hn::Set(d, 4.0)), upper);
        v[2] = upper[1];
    } else if constexpr (sizeof(T) == 1) {
        const hn::Rebind<std::int32_t, D> di;
        const hn::Rebind<std::uint32_t, D> du;
        const auto oi = hn::DemoteTo(di, o);
        const auto o4 = hn::Min(oi, hn::Set(di, static_cast<std::int32_t>(bytes - 4)));
        auto w = hn::BitCast(du, gather::Words(di, reinterpret_cast<const std::int32_t*>(src.data), o4));
        w = hn::operator>>(w, hn::BitCast(du, hn::ShiftLeft<3>(hn::Sub(oi, o4))));
        const auto wi = hn::BitCast(di, w);
        if constexpr (std::is_signed_v<T>) {
            v[0] = hn::PromoteTo(d, hn::ShiftRight<24>(hn::ShiftLeft<24>(wi)));
            v[1] = hn::PromoteTo(d, hn::ShiftRight<24>(hn::ShiftLeft<16>(wi)));
            v[2] = hn::PromoteTo(d, hn::ShiftRight<24>(hn::ShiftLeft<8>(wi)));
        } else {
            const auto m = hn::Set(du, 0xFFu);
            v[0] = hn::PromoteTo(d, hn::BitCast(di, hn::And(w, m)));
            v[1] = hn::PromoteTo(d, hn::BitCast(di, hn::And(hn::ShiftRight<8>(w), m)));
            v[2] = hn::PromoteTo(d, hn::BitCast(di, hn::And(hn::ShiftRight<16>(w), m)));
        }
    } else {
        const hn::Rebind<std::int64_t, D> dl;
        const hn::Rebind<std::uint64_t, D> dq;
        const auto ol = hn::ConvertTo(dl, o);
        const auto o8 = hn::Min(ol, hn::Set(dl, bytes - 8));
        auto w = gather::Words(dq, static_cast<const std::uint64_t*>(src.data), o8);
        w = hn::operator>>(w, hn::BitCast(dq, hn::ShiftLeft<3>(hn::Sub(ol, o8))));
        const auto wl = hn::BitCast(dl, w);
        if constexpr (std::is_signed_v<T>) {
            v[0] = hn::ConvertTo(d, hn::ShiftRight<48>(hn::ShiftLeft<48>(wl)));
            v[1] = hn::ConvertTo(d, hn::ShiftRight<48>(hn::ShiftLeft<32>(wl)));
            v[2] = hn::ConvertTo(d, hn::ShiftRight<48>(hn::ShiftLeft<16>(wl)));
        } else {
            const auto m = hn::Set(dq, 0xFFFFu);
            v[0] = hn::ConvertTo(d, hn::BitCast(dl, hn::And(w, m)));
            v[1] = hn::ConvertTo(d, hn::BitCast(dl, hn::And(hn::ShiftRight<16>(w), m)));
            v[2] = hn::ConvertTo(d, hn::BitCast(dl, hn::And(hn::ShiftRight<32>(w), m)));
        }
    }
}

/// GridSampler::locate of coordinate `a` of lanes b … b + N − 1: clamped
/// to [0, n − 1], the cell (≤ n − 2) and the fraction.
HWY_INLINE void locate(D d, const BatchSource& src, int a, V p, std::size_t b, double (*cell)[kBatch],
                       double (*frac)[kBatch]) {
    const std::int64_t n = a == 0 ? src.nx : a == 1 ? src.ny : src.nz;
    const V x = hn::Min(hn::Max(p, hn::Zero(d)), hn::Set(d, static_cast<double>(n - 1)));
    const V i = hn::Min(hn::Floor(x), hn::Set(d, static_cast<double>(n - 2)));
    hn::Store(i, d, cell[a] + b);
    hn::Store(hn::Sub(x, i), d, frac[a] + b);
}

/// The positions of samples j0 + b … j0 + b + N − 1: t = t_near + (j −
/// first + offset)·δ, p = p0 + dp·t (SampleGrid::at, RaySpan::at).
HWY_INLINE void positions(D d, const RayGrid& ray, std::int64_t j0, std::size_t b, V* p) {
    const V jj = hn::Iota(d, static_cast<double>(j0 + static_cast<std::int64_t>(b) - ray.first));
    const V t =
        hn::Add(hn::Set(d, ray.t_near), hn::Mul(hn::Add(jj, hn::Set(d, ray.offset)), hn::Set(d, ray.delta)));
    p[0] = hn::Add(hn::Set(d, ray.p0.x), hn::Mul(hn::Set(d, ray.dp.x), t));
    p[1] = hn::Add(hn::Set(d, ray.p0.y), hn::Mul(hn::Set(d, ray.dp.y), t));
    p[2] = hn::Add(hn::Set(d, ray.p0.z), hn::Mul(hn::Set(d, ray.dp.z), t));
}

/// Whether trilinear gathers corner pairs for samples of type T.
template <class T>
HWY_INLINE bool gathers_pairs(const BatchSource& src) {
    if constexpr (kPairs<T>) {
        return sizeof(T) == 4 || src.bricks_x > 0 ||
               src.nx * src.ny * src.nz * static_cast<std::int64_t>(sizeof(T)) <= kPairBytesMax;
    } else {
        return false;
    }
}

/// GridSampler::interpolate of the located cells of lanes b0 … b1 − 1
/// (whole vectors): corner pairs gathered where the type has them, the
/// corners loaded one by one otherwise.
template <class T>
HWY_INLINE void trilinear(const BatchSource& src, const double (*cell)[kBatch], const double (*frac)[kBatch],
                          std::size_t b0, std::size_t b1, double* out, bool skip_inactive) {
    const D d;
    const std::size_t N = hn::Lanes(d);
    if constexpr (kPairs<T>) {
        // Each gather fetches a corner and its +x neighbour at once (4
        // gathers for 8 corners), in vectors.
        if (gathers_pairs<T>(src)) {
            pair_corners<T>(src, cell, frac, b0, b1, out, skip_inactive && src.active != nullptr);
            return;
        }
    }
    const T* data = static_cast<const T*>(src.data);
    const std::int64_t sy = src.nx, sz = src.nx * src.ny;
    HWY_ALIGN double corner[8][kBatch];
    for (std::size_t b = b0; b < b1; ++b) {
        const std::int64_t base =
            static_cast<std::int64_t>(cell[0][b]) +
            src.nx * (static_cast<std::int64_t>(cell[1][b]) + src.ny * static_cast<std::int64_t>(cell[2][b]));
        const T* q = data + base;
        corner[0][b] = static_cast<double>(q[0]);
        corner[1][b] = static_cast<double>(q[1]);
        corner[2][b] = static_cast<double>(q[sy]);
        corner[3][b] = static_cast<double>(q[sy + 1]);
        corner[4][b] = static_cast<double>(q[sz]);
        corner[5][b] = static_cast<double>(q[sz + 1]);
        corner[6][b] = static_cast<double>(q[sz + sy]);
        corner[7][b] = static_cast<double>(q[sz + sy + 1]);
    }
    for (std::size_t b = b0; b < b1; b += N) {
        V c[8];
        for (int k = 0; k < 8; ++k) c[k] = hn::Load(d, corner[k] + b);
        hn::Store(Lerp8(c, hn::Load(d, frac[0] + b), hn::Load(d, frac[1] + b), hn::Load(d, frac[2] + b)), d,
                  out + b);
    }
}

/// The trilinear scalar (GridSampler's operations) of samples j0 ..
/// j0 + count − 1, rounded up to whole vectors; returns how many it wrote.
template <class T>
std::size_t interpolate_typed(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count,
                              double* out, bool skip_inactive = false) {
    const D d;
    const std::size_t N = hn::Lanes(d);
    HWY_ALIGN double cell[3][kBatch];
    HWY_ALIGN double frac[3][kBatch];
    // whole vectors covering count samples
    const std::size_t used = std::min<std::size_t>(kBatch, (static_cast<std::size_t>(count) + N - 1) / N * N);
    for (std::size_t b = 0; b < used; b += N) {
        V p[3];
        positions(d, ray, j0, b, p);
        for (int a = 0; a < 3; ++a) locate(d, src, a, p[a], b, cell, frac);
    }
    trilinear<T>(src, cell, frac, 0, used, out, skip_inactive);
    return used;
}

/// The differences f(p + h·e_a) − f(p − h·e_a), a = x, y, z, of lanes b …
/// b + N − 1 (8-, 16-bit and float32 samples, x-fastest) from 8 gathers
/// (12 for float32) instead of the six points' 24, where in every lane each axis's two
/// points lie in neighbouring cells and p's own cell is one of them; false
/// (nothing written) elsewhere. Their corners then lie in 8 rows of
/// x-pairs: the 4 rows of p's cell, gathered as x-triples from the lower
/// point's x cell (p's x-pair selected per lane), and one row more beyond
/// them along y and along z, gathered as pairs at p's x cell. Each point
/// takes the corners and fractions of its own trilinear lookup, so the
/// differences are the same bits as two trilinear lookups per axis.
template <class T>
HWY_INLINE bool shared_differences(const BatchSource& src, const V* p, std::size_t b, V* diff) {
    const D d;
    const V h = hn::Set(d, kGradientStep), one = hn::Set(d, 1.0);
    HWY_ALIGN double cell[3][kBatch];
    HWY_ALIGN double frac[3][kBatch];
    HWY_ALIGN double cell_lo[3][kBatch];
    HWY_ALIGN double frac_lo[3][kBatch];
    HWY_ALIGN double cell_hi[3][kBatch];
    HWY_ALIGN double frac_hi[3][kBatch];
    V c[3], lo[3];
    M same[3];  // p's cell is the lower point's (else the upper one's)
    for (int a = 0; a < 3; ++a) {
        locate(d, src, a, p[a], b, cell, frac);
        locate(d, src, a, hn::Sub(p[a], h), b, cell_lo, frac_lo);
        locate(d, src, a, hn::Add(p[a], h), b, cell_hi, frac_hi);
        c[a] = hn::Load(d, cell[a] + b);
        lo[a] = hn::Load(d, cell_lo[a] + b);
        const V next = hn::Add(lo[a], one);
        same[a] = hn::Eq(c[a], lo[a]);
        if (!hn::AllTrue(
                d, hn::And(hn::Eq(hn::Load(d, cell_hi[a] + b), next), hn::Or(same[a], hn::Eq(c[a], next)))))
            return false;
    }
    V f[3], fl[3], fh[3];
    for (int a = 0; a < 3; ++a) {
        f[a] = hn::Load(d, frac[a] + b);
        fl[a] = hn::Load(d, frac_lo[a] + b);
        fh[a] = hn::Load(d, frac_hi[a] + b);
    }
    constexpr double size = sizeof(T);
    const double sy = static_cast<double>(src.nx) * size, sz = sy * static_cast<double>(src.ny);
    const V nx = hn::Set(d, static_cast<double>(src.nx)), ny = hn::Set(d, static_cast<double>(src.ny));
    auto offset = [&](V x, V y, V z) {  // node (x, y, z)'s byte offset: an exact integer
        return hn::Mul(hn::Add(x, hn::Mul(nx, hn::Add(y, hn::Mul(ny, z)))), hn::Set(d, size));
    };
    struct Pair {
        V v[2];
    };
    auto pair = [&](V o) {
        Pair r;
        gather_x_pair<T>(d, src, o, r.v);
        return r;
    };
    auto pick = [&](M m, const Pair& x, const Pair& y) {
        return Pair{{hn::IfThenElse(m, x.v[0], y.v[0]), hn::IfThenElse(m, x.v[1], y.v[1])}};
    };
    // the corners of x-pair rows r[0..3] ((y, z) = (0, 0), (1, 0), (0, 1), (1, 1)) at fractions fx, fy, fz
    auto lerp = [&](const Pair* r, V fx, V fy, V fz) {
        V k[8];
        for (int i = 0; i < 4; ++i) {
            k[2 * i] = r[i].v[0];
            k[2 * i + 1] = r[i].v[1];
        }
        return Lerp8(k, fx, fy, fz);
    };
    // x: the triples of p's rows from the lower x cell; P: p's x-pairs
    const V core = offset(lo[0], c[1], c[2]);
    Pair low[4], high[4], P[2][2];  // P[y][z]
    for (int i = 0; i < 4; ++i) {
        const int y = i & 1, z = i >> 1;
        V t[3];
        gather_triple<T>(d, src, hn::Add(core, hn::Set(d, z * sz + y * sy)), t);
        low[i] = Pair{{t[0], t[1]}};
        high[i] = Pair{{t[1], t[2]}};
        P[y][z] = pick(same[0], low[i], high[i]);
    }
    diff[0] = hn::Sub(lerp(high, fh[0], f[1], f[2]), lerp(low, fl[0], f[1], f[2]));
    // y: rows lo_y, lo_y + 1, lo_y + 2; the one beyond p's cell gathered
    const V ey = hn::IfThenElse(same[1], hn::Add(lo[1], hn::Set(d, 2.0)), lo[1]);
    for (int z = 0; z < 2; ++z) {
        const Pair beyond = pair(hn::Add(offset(c[0], ey, c[2]), hn::Set(d, z * sz)));
        const Pair r0 = pick(same[1], P[0][z], beyond), r1 = pick(same[1], P[1][z], P[0][z]),
                   r2 = pick(same[1], beyond, P[1][z]);
        low[2 * z] = r0;
        low[2 * z + 1] = r1;
        high[2 * z] = r1;
        high[2 * z + 1] = r2;
    }
    diff[1] = hn::Sub(lerp(high, f[0], fh[1], f[2]), lerp(low, f[0], fl[1], f[2]));
    // z: rows lo_z, lo_z + 1, lo_z + 2
    const V ez = hn::IfThenElse(same[2], hn::Add(lo[2], hn::Set(d, 2.0)), lo[2]);
    for (int y = 0; y < 2; ++y) {
        const Pair beyond = pair(hn::Add(offset(c[0], c[1], ez), hn::Set(d, y * sy)));
        const Pair s0 = pick(same[2], P[y][0], beyond), s1 = pick(same[2], P[y][1], P[y][0]),
                   s2 = pick(same[2], beyond, P[y][1]);
        low[y] = s0;
        low[2 + y] = s1;
        high[y] = s1;
        high[2 + y] = s2;
    }
    diff[2] = hn::Sub(lerp(high, f[0], f[1], fh[2]), lerp(low, f[0], f[1], fl[2]));
    return true;
}

/// ShadedScalarMedium::factors at index-space points p, each lane's unit
/// vector toward the eye `view` (ShadedScalarMedium::view: a ray's own in
/// packets), with on-the-fly gradients: D (diffuse), S (specular) and the
/// gradient-opacity factor f. The gradient of world_gradient (central
/// differences of the trilinear field, then the chain rule), the factors of
/// shade_factors and gradient_factor: the same operations in the same
/// order, so the same bits; std::pow (a shininess that is not a whole
/// number) and the gradient-opacity function are evaluated lane by lane.
template <class T>
HWY_INLINE void ShadeFactorsAt(D d, const BatchSource& src, const V* p, const V* view, V* diffuse,
                               V* specular, V& opacity) {
    const ShadeSetup& sh = *src.shade;
    const std::size_t N = hn::Lanes(d);
    constexpr std::size_t b = 0;  // the lanes' place in the arrays below
    HWY_ALIGN double cell[3][kBatch];
    HWY_ALIGN double frac[3][kBatch];
    HWY_ALIGN double value[kBatch];
    const V h = hn::Set(d, kGradientStep);
    // The two points of each axis usually lie in neighbouring cells, p's
    // own among them: their corners then share rows (shared_differences).
    const bool share =
        kPairs<T> && src.bricks_x == 0 &&
        (sizeof(T) == 4 || src.nx * src.ny * src.nz * static_cast<std::int64_t>(sizeof(T)) <= kPairBytesMax);
    V du[3];
    if (share && shared_differences<T>(src, p, b, du)) {
        for (auto& g : du) g = hn::Div(g, hn::Set(d, 2 * kGradientStep));
    } else {
        for (int a = 0; a < 3; ++a) {
            V side[2];
            for (int k = 0; k < 2; ++k) {  // p + h·e_a, then p − h·e_a
                for (int e = 0; e < 3; ++e)
                    locate(d, src, e,
                           e != a   ? p[e]
                           : k == 0 ? hn::Add(p[e], h)
                                    : hn::Sub(p[e], h),
                           b, cell, frac);
                trilinear<T>(src, cell, frac, b, b + N, value, false);
                side[k] = hn::Load(d, value + b);
            }
            du[a] = hn::Div(hn::Sub(side[0], side[1]), hn::Set(d, 2 * kGradientStep));
        }
    }
    V grad[3];
    for (int i = 0; i < 3; ++i) {
        V r = hn::Zero(d);
        for (int j = 0; j < 3; ++j) r = exp_v::Fma(hn::Set(d, sh.world_to_index.m[j][i]), du[j], r);
        grad[i] = r;
    }
    auto dot = [&](const V* a, const V* v) {
        return exp_v::Fma(a[2], v[2], exp_v::Fma(a[1], v[1], hn::Mul(a[0], v[0])));
    };
    const V len =
        hn::Sqrt(exp_v::Fma(grad[2], grad[2], exp_v::Fma(grad[1], grad[1], hn::Mul(grad[0], grad[0]))));
    for (int c = 0; c < 3; ++c) {
        diffuse[c] = hn::Set(d, sh.light ? sh.ka : 1.0);
        specular[c] = hn::Zero(d);
    }
    if (sh.light) {
        const auto normal = hn::Gt(len, hn::Zero(d));  // else lit as facing every light, no highlight
        const V inv = hn::Div(hn::Set(d, 1.0), len);
        const V n[3] = {hn::Mul(grad[0], inv), hn::Mul(grad[1], inv), hn::Mul(grad[2], inv)};
        auto light = [&](const V* l, const Rgb& color) {  // l: a direction per lane
            const V ndl = hn::Abs(dot(n, l));
            // shade_factors' hv = l + view, its length and n·hv/|hv|, per lane
            const V hv[3] = {hn::Add(l[0], view[0]), hn::Add(l[1], view[1]), hn::Add(l[2], view[2])};
            const V hl = hn::Sqrt(
                hn::Add(hn::Add(hn::Mul(hv[0], hv[0]), hn::Mul(hv[1], hv[1])), hn::Mul(hv[2], hv[2])));
            const M lit = hn::Gt(hl, hn::Zero(d));
            const V ndh = hn::IfThenElseZero(
                lit, hn::Div(hn::Abs(dot(n, hv)), hn::IfThenElse(lit, hl, hn::Set(d, 1.0))));
            V spec = hn::Zero(d);
            if (sh.ks > 0 && whole_shininess(sh.p)) {  // highlight_pow's squarings
                auto n = static_cast<unsigned>(sh.p);
                V r = hn::Set(d, 1.0), base = ndh;
                for (;;) {
                    if ((n & 1u) != 0) r = hn::Mul(r, base);
                    n >>= 1;
                    if (n == 0) break;
                    base = hn::Mul(base, base);
                }
                spec = hn::Mul(hn::Set(d, sh.ks), r);
            } else if (sh.ks > 0) {
                HWY_ALIGN double x[8];
                hn::Store(ndh, d, x);
                for (std::size_t l = 0; l < N; ++l) x[l] = sh.ks * std::pow(x[l], sh.p);
                spec = hn::Load(d, x);
            }
            const V kd = hn::Set(d, sh.kd);
            for (int c = 0; c < 3; ++c) {
                diffuse[c] =
                    hn::IfThenElse(normal, exp_v::Fma(hn::Mul(kd, ndl), hn::Set(d, color[c]), diffuse[c]),
                                   hn::Add(diffuse[c], hn::Set(d, sh.kd * color[c])));
                specular[c] =
                    hn::IfThenElse(normal, exp_v::Fma(spec, hn::Set(d, color[c]), specular[c]), specular[c]);
            }
        };
        if (sh.lights.empty()) {
            light(view, {1, 1, 1});
        } else {
            for (const Light& l : sh.lights) {
                const V dir[3] = {hn::Set(d, l.direction.x), hn::Set(d, l.direction.y),
                                  hn::Set(d, l.direction.z)};
                light(dir, l.color);
            }
        }
    }
    opacity = hn::Set(d, 1.0);
    if (sh.modulate != nullptr) {
        HWY_ALIGN double x[8];
        hn::Store(len, d, x);
        for (std::size_t l = 0; l < N; ++l) x[l] = sh.modulate->gradient_factor(x[l]);
        opacity = hn::Load(d, x);
    }
}

/// ShadeFactorsAt for the points j0 + b … j0 + b + N − 1 of `ray`.
template <class T>
HWY_INLINE void ShadeFactorsLanes(D d, const BatchSource& src, const RayGrid& ray, std::int64_t j0,
                                  std::size_t b, V* diffuse, V* specular, V& opacity) {
    V p[3];
    positions(d, ray, j0, b, p);
    const V view[3] = {hn::Set(d, ray.view.x), hn::Set(d, ray.view.y), hn::Set(d, ray.view.z)};
    ShadeFactorsAt<T>(d, src, p, view, diffuse, specular, opacity);
}

/// ShadedScalarMedium::shade of the samples j0 + b … j0 + b + N − 1: σ and
/// the source g (after ScalarMedium::classify, before the model) become
/// σ·f and (g·D + σ·S)·f.
template <class T>
HWY_INLINE void ShadeLanes(D d, const BatchSource& src, const RayGrid& ray, std::int64_t j0, std::size_t b,
                           V& sigma, V* g) {
    V diffuse[3], specular[3], opacity;
    ShadeFactorsLanes<T>(d, src, ray, j0, b, diffuse, specular, opacity);
    for (int c = 0; c < 3; ++c)
        g[c] = hn::Mul(exp_v::Fma(g[c], diffuse[c], hn::Mul(sigma, specular[c])), opacity);
    sigma = hn::Mul(sigma, opacity);
}

/// The segments of lanes b … b + N − 1 (BatchSource::rule) from their σ and
/// source g (ScalarMedium::classify's, shaded where the medium is): as
/// apply_model and point_rules.h, lane by lane. Lanes whose optical depth
/// lies outside exp_neg's reduction (or is NaN) take the scalar rule.
HWY_INLINE void ApplyRule(D d, const BatchSource& src, double delta, std::size_t b, V sigma, const V* source,
                          BatchOut& out) {
    V g[3];
    for (int k = 0; k < 3; ++k) g[k] = src.model == Model::absorption ? hn::Zero(d) : source[k];
    const V sa = src.model == Model::emission ? hn::Zero(d) : sigma;
    const V dl = hn::Set(d, delta);
    const V x = hn::Mul(sa, dl);
    V t, weight;
    if (src.rule == PointRule::alpha) {
        const V alpha = exp_v::OneMinusExpNeg(d, x);
        weight = hn::IfThenElse(hn::Gt(sa, hn::Zero(d)), hn::Div(alpha, sa), dl);
        t = hn::Sub(hn::Set(d, 1.0), alpha);
    } else {
        t = exp_v::ExpNeg(d, x);
        weight = dl;
    }
    hn::Store(t, d, out.t + b);
    for (int k = 0; k < 3; ++k) hn::Store(hn::Mul(g[k], weight), d, out.radiance[k] + b);
    const auto outside = hn::Not(exp_v::InRange(d, x));
    if (hn::AllFalse(d, outside)) return;
    HWY_ALIGN double s[8];
    HWY_ALIGN double gs[3][8];
    hn::Store(sa, d, s);
    for (int k = 0; k < 3; ++k) hn::Store(g[k], d, gs[k]);
    std::uint8_t bits[8] = {};
    hn::StoreMaskBits(d, outside, bits);  // N ≤ 8 lanes of doubles
    for (std::size_t l = 0; l < hn::Lanes(d); ++l) {
        if (((bits[0] >> l) & 1u) == 0) continue;
        const std::size_t i = b + l;
        const MediumSample m{s[l], {gs[0][l], gs[1][l], gs[2][l]}};
        const Segment seg =
            src.rule == PointRule::alpha ? alpha_segment(m, delta) : riemann_segment(m, delta);
        out.t[i] = seg.transmittance;
        for (int k = 0; k < 3; ++k) out.radiance[k][i] = seg.radiance[k];
    }
}

template <class T>
void classify_typed(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, BatchOut& out) {
    const D d;
    HWY_ALIGN double values[kBatch];
    // vectors of samples in inactive cells come back as −∞: below zero_below
    const std::size_t used = interpolate_typed<T>(src, ray, j0, count, values, true);
    const V zero_below = hn::Set(d, src.zero_below);
    out.zero = 0;
    for (std::size_t b = 0; b < used; b += hn::Lanes(d)) {
        const V v = hn::Load(d, values + b);
        const auto below = hn::Lt(v, zero_below);
        std::uint8_t bits[8] = {};
        hn::StoreMaskBits(d, below, bits);  // N ≤ 8 lanes of doubles
        out.zero |= static_cast<std::uint32_t>(bits[0]) << b;
        if (hn::AllTrue(d, below)) {  // the medium is zero: σ = 0 and g = 0 downstream
            hn::Store(hn::Zero(d), d, out.sigma + b);
            for (int k = 0; k < 3; ++k) hn::Store(hn::Zero(d), d, out.color[k] + b);
            if (src.rule != PointRule::none) {
                hn::Store(hn::Set(d, 1.0), d, out.t + b);
                for (int k = 0; k < 3; ++k) hn::Store(hn::Zero(d), d, out.radiance[k] + b);
            }
            continue;
        }
        V r[3];
        eval(d, *src.sigma, v, r);
        V sigma = r[0];
        hn::Store(sigma, d, out.sigma + b);
        eval(d, *src.color, v, r);
        for (int k = 0; k < 3; ++k) hn::Store(r[k], d, out.color[k] + b);
        if (src.rule == PointRule::none) continue;
        V g[3];  // ScalarMedium::classify: c·σ, or q
        for (int k = 0; k < 3; ++k) g[k] = src.associated ? r[k] : hn::Mul(r[k], sigma);
        if (src.shade != nullptr) ShadeLanes<T>(d, src, ray, j0, b, sigma, g);
        ApplyRule(d, src, ray.delta, b, sigma, g, out);
    }
}

/// Bytes of `bytes` (size ≥ 4) at indices i (exact integers in doubles), as doubles.
HWY_INLINE V GatherBytes(D d, const std::uint8_t* bytes, std::int64_t size, V i) {
    const hn::Rebind<std::int32_t, D> di;
    const hn::Rebind<std::uint32_t, D> du;
    const auto o = hn::DemoteTo(di, i);
    const auto o4 = hn::Min(o, hn::Set(di, static_cast<std::int32_t>(size - 4)));
    auto w = hn::BitCast(du, gather::Words(di, reinterpret_cast<const std::int32_t*>(bytes), o4));
    w = hn::operator>>(w, hn::BitCast(du, hn::ShiftLeft<3>(hn::Sub(o, o4))));
    return hn::PromoteTo(d, hn::BitCast(di, hn::And(w, hn::Set(du, 0xFFu))));
}

/// Vectors of lanes in a packet: two, so that one vector's gathers overlap
/// the other's arithmetic, and each branch serves both.
constexpr std::size_t kPacketVectors = 2;
constexpr std::size_t kPacketLanesMax = 8 * kPacketVectors;  // 8 doubles to a vector at most
/// Samples a lane takes per step: its next ones, in its run and on into the
/// next run found, so that a step's bookkeeping serves several samples and
/// their gathers overlap.
constexpr std::size_t kSteps = 6;
/// How far ahead of a step's first sample (two steps) a lane prefetches its
/// cell's corner rows.
constexpr std::size_t kPrefetchAhead = 12;
/// The runs a lane's walk may find ahead of its samples.
constexpr std::size_t kPacketQueue = 2;
constexpr std::size_t kPacketGroups = (kPacketLanesMax + kBatch - 1) / kBatch;  // of kBatch lanes

/// The lanes of a packet: one ray each (PacketRay's fields, lane by lane),
/// its place in the sample grid, its walk and its accumulators.
struct PacketLanes {
    static constexpr std::size_t L = kPacketLanesMax;
    HWY_ALIGN double p0[3][L], dp[3][L], tn[L], dl[L], off[L], n[L], A[3][L], B[3][L], before[L], after[L];
    HWY_ALIGN double i[L];        // the next sample
    HWY_ALIGN double run_end[L];  // the last sample of the run being evaluated (< i: none)
    // the next non-empty runs, found by the walk ahead of the samples
    // (start > end: none), in order: [0] before [1]
    HWY_ALIGN double next_start[kPacketQueue][L], next_end[kPacketQueue][L];
    HWY_ALIGN double w[L];  // where the walk goes on
    HWY_ALIGN double T[L], C[3][L];
    HWY_ALIGN double live[L];     // 1: the lane holds a ray
    HWY_ALIGN double main[L];     // the ray's main axis (its largest |dp|): 0, 1 or 2
    HWY_ALIGN double sure[L];     // 1: its empty runs' exits need no check (exits_are_sure)
    HWY_ALIGN double view[3][L];  // shaded: the unit vector toward the eye (ShadedScalarMedium::view)
    HWY_ALIGN double weighted[L], first[L];  // depth outputs: DepthTrack's sums
    std::int64_t ray[L];

    /// Lane l takes ray k (or none, k < 0: it stays dead, at safe values);
    /// shaded, with the lattice's index-to-world matrix (else nullptr).
    void load(std::size_t l, const PacketRay* r, std::int64_t k, bool exit_sure, const Mat3* index_to_world) {
        ray[l] = k;
        live[l] = r != nullptr ? 1.0 : 0.0;
        for (int a = 0; a < 3; ++a) {
            p0[a][l] = r != nullptr ? r->p0[a] : 0.0;
            dp[a][l] = r != nullptr ? r->dp[a] : 0.0;
            A[a][l] = r != nullptr ? r->A[a] : 0.0;
            B[a][l] = r != nullptr ? r->B[a] : 0.0;
            C[a][l] = 0.0;
        }
        main[l] = r != nullptr ? packet_main_axis(r->dp) : 0.0;
        if (index_to_world != nullptr) {
            const Vec3 v = r != nullptr ? view_toward_eye(*index_to_world, {r->dp[0], r->dp[1], r->dp[2]})
                                        : Vec3{0, 0, 1};
            for (int a = 0; a < 3; ++a) view[a][l] = v[a];
        }
        sure[l] = r != nullptr && exit_sure ? 1.0 : 0.0;
        tn[l] = r != nullptr ? r->t_near : 0.0;
        dl[l] = r != nullptr ? r->delta : 0.0;
        off[l] = r != nullptr ? r->offset : 0.0;
        n[l] = r != nullptr ? r->n : 0.0;
        before[l] = r != nullptr ? r->before : -1.0;
        after[l] = r != nullptr ? r->after : 2.0;
        i[l] = w[l] = 1.0;
        run_end[l] = 0.0;
        for (std::size_t q = 0; q < kPacketQueue; ++q) {
            next_start[q][l] = 1.0;
            next_end[q][l] = 0.0;
        }
        T[l] = 1.0;
        weighted[l] = 0.0;
        first[l] = INFINITY;
    }
};

/// Lanes o … o + N − 1 in `m` make the first run of their queue (qs, qe:
/// its places, loaded) their current one, to its last sample (else `re`
/// stays), and their queue moves up; the places are stored and left in qs,
/// qe. The caller sets the lanes' next sample.
HWY_INLINE void TakeQueuedRun(D d, PacketLanes& L, std::size_t o, M m, V re, V* qs, V* qe) {
    hn::Store(hn::IfThenElse(m, qe[0], re), d, L.run_end + o);
    for (std::size_t q = 0; q < kPacketQueue; ++q) {
        const bool last_place = q + 1 == kPacketQueue;
        qs[q] = hn::IfThenElse(m, last_place ? hn::Set(d, 1.0) : qs[q + 1], qs[q]);
        qe[q] = hn::IfThenElse(m, last_place ? hn::Zero(d) : qe[q + 1], qe[q]);
        hn::Store(qs[q], d, L.next_start[q] + o);
        hn::Store(qe[q], d, L.next_end[q] + o);
    }
}

/// Positions of samples j of the rays of lanes o … o + N − 1: SampleGrid::at (first = 1).
HWY_INLINE void LanePositions(D d, const PacketLanes& L, std::size_t o, V j, V* p) {
    const V t =
        hn::Add(hn::Load(d, L.tn + o),
                hn::Mul(hn::Add(hn::Sub(j, hn::Set(d, 1.0)), hn::Load(d, L.off + o)), hn::Load(d, L.dl + o)));
    for (int a = 0; a < 3; ++a)
        p[a] = hn::Add(hn::Load(d, L.p0[a] + o), hn::Mul(hn::Load(d, L.dp[a] + o), t));
}

/// MacrocellLattice::macrocell per lane.
HWY_INLINE void LaneMacrocells(D d, const PacketWalk& w, const V* p, V* m) {
    const V per = hn::Set(d, 1.0 / static_cast<double>(std::int64_t{1} << w.shift));  // exact
    for (int a = 0; a < 3; ++a) {
        const V x = hn::Min(hn::Max(p[a], hn::Zero(d)), hn::Set(d, w.nodes[a] - 1.0));
        const V c = hn::Min(hn::Floor(x), hn::Set(d, w.nodes[a] - 2.0));
        m[a] = hn::Floor(hn::Mul(c, per));
    }
}

/// RunFinder::run(j, +1, n) for the lanes o … o + N − 1 in `need`, from
/// j = L.w: the walk moves past the run, and a non-empty one joins the
/// lane's queue. With `queued` (pre-integration's ends), it joins widened
/// by a sample on either side, from past the last one queued (`queued`,
/// per lane, which it updates), so that every segment with an end in it is
/// sampled, each end once.
HWY_INLINE void WalkLanes(D d, const PacketWalk& w, PacketLanes& L, std::size_t o, M need,
                          double* queued = nullptr) {
    const V j = hn::Load(d, L.w + o), lim = hn::Load(d, L.n + o);
    const V before = hn::Load(d, L.before + o), after = hn::Load(d, L.after + o);
    const M pre = hn::And(need, hn::Le(j, before));
    const M post = hn::AndNot(pre, hn::And(need, hn::Ge(j, after)));
    V last = hn::IfThenElse(pre, hn::Min(before, lim), lim);
    M empty = hn::Or(pre, post);
    const M mid = hn::AndNot(empty, need);
    if (!hn::AllFalse(d, mid)) {
        V p[3], m[3];
        LanePositions(d, L, o, j, p);
        for (auto& x : p) x = hn::IfThenElseZero(mid, x);
        LaneMacrocells(d, w, p, m);
        const V idx = hn::Add(
            m[0], hn::Mul(hn::Set(d, w.dims[0]), hn::Add(m[1], hn::Mul(hn::Set(d, w.dims[1]), m[2]))));
        const M is_empty = hn::And(mid, hn::Ne(GatherBytes(d, w.empty, w.cells, idx), hn::Zero(d)));
        const V r = hn::Sub(GatherBytes(d, w.ahead, w.cells, idx), hn::Set(d, 1.0));
        // along the ray's main axis (its largest |dp|), the longer box of
        // EmptySpace::along: r across, r_main along
        const V axis = hn::Load(d, L.main + o);
        const V r_main =
            hn::Sub(GatherBytes(d, w.along, 3 * w.cells,
                                hn::Add(idx, hn::Mul(axis, hn::Set(d, static_cast<double>(w.cells))))),
                    hn::Set(d, 1.0));
        const V edge = hn::Set(d, static_cast<double>(std::int64_t{1} << w.shift));
        V lo[3], hi[3];
        V x = hn::Set(d, INFINITY);
        for (int a = 0; a < 3; ++a) {  // EmptySpace::box_ahead, box_face
            const bool down = ((w.octant >> a) & 1) != 0;
            const V ra = hn::IfThenElse(hn::Eq(axis, hn::Set(d, static_cast<double>(a))), r_main, r);
            lo[a] = down ? hn::Max(hn::Sub(m[a], ra), hn::Zero(d)) : m[a];
            hi[a] = down ? m[a] : hn::Min(hn::Add(m[a], ra), hn::Set(d, w.dims[a] - 1.0));
            const V face =
                down ? hn::Mul(lo[a], edge)
                     : hn::Min(hn::Mul(hn::Add(hi[a], hn::Set(d, 1.0)), edge), hn::Set(d, w.nodes[a] - 1.0));
            x = hn::Min(x, hn::Add(hn::Mul(face, hn::Load(d, L.A[a] + o)), hn::Load(d, L.B[a] + o)));
        }
        // RunFinder::estimated_last: the exit, clamped to [j, n], floored;
        // short of it by kExitMargin for the empty runs whose exits are sure
        const M finite = hn::IsFinite(x);
        const M sure = hn::And(hn::And(is_empty, finite), hn::Eq(hn::Load(d, L.sure + o), hn::Set(d, 1.0)));
        const V xs = hn::IfThenElse(sure, hn::Sub(x, hn::Set(d, kExitMargin)), x);
        V k = hn::IfThenElse(finite, hn::Floor(hn::Min(hn::Max(xs, j), lim)), lim);
        // RunFinder::last_in for the other empty ones: verified on the computed positions
        for (M check = hn::AndNot(sure, is_empty); !hn::AllFalse(d, check);) {
            V pk[3], mk[3];
            LanePositions(d, L, o, k, pk);
            for (auto& c : pk) c = hn::IfThenElseZero(check, c);
            LaneMacrocells(d, w, pk, mk);
            M in_box = hn::Eq(k, j);
            M inside = hn::Not(in_box);
            for (int a = 0; a < 3; ++a)
                inside = hn::And(inside, hn::And(hn::Ge(mk[a], lo[a]), hn::Le(mk[a], hi[a])));
            check = hn::AndNot(hn::Or(in_box, inside), check);
            k = hn::IfThenElse(check, hn::Sub(k, hn::Set(d, 1.0)), k);
        }
        last = hn::IfThenElse(mid, k, last);
        empty = hn::Or(empty, is_empty);
    }
    const M found = hn::AndNot(empty, need);
    const V one = hn::Set(d, 1.0);
    hn::Store(hn::IfThenElse(need, hn::Add(last, one), j), d, L.w + o);
    V start = j, end = last;
    if (queued != nullptr) {
        const V before_run = hn::Load(d, queued + o);
        start = hn::Max(hn::Sub(j, one), hn::Add(before_run, one));
        end = hn::Min(hn::Add(last, one), lim);
        hn::Store(hn::IfThenElse(found, end, before_run), d, queued + o);
    }
    // into the first free place of the lane's queue
    M free = found;
    for (std::size_t q = 0; q < kPacketQueue; ++q) {
        const V qs = hn::Load(d, L.next_start[q] + o), qe = hn::Load(d, L.next_end[q] + o);
        const M put = hn::AndNot(hn::Le(qs, qe), free);
        hn::Store(hn::IfThenElse(put, start, qs), d, L.next_start[q] + o);
        hn::Store(hn::IfThenElse(put, end, qe), d, L.next_end[q] + o);
        free = hn::AndNot(put, free);
    }
}

/// ShadeFactorsAt's factors per lane.
struct LaneShade {
    V diffuse[3], specular[3], opacity;
};

/// The segments of one sample per lane (ClassifyBatch's operations: the
/// transfer function, with `shade` (ShadeFactorsAt's factors at the
/// samples' points, else nullptr) the shading, the model, the rule), (1, 0)
/// where `zero`.
HWY_INLINE void LaneSegments(D d, const BatchSource& src, bool shared, V v, V dl, M zero,
                             const LaneShade* shade, V& t, V* rad) {
    const V one = hn::Set(d, 1.0);
    V r[3];
    V sigma;
    if (shared) {
        const KnotPiece p(d, *src.sigma, v);
        on_knot_piece(d, *src.sigma, p, r);
        sigma = r[0];
        on_knot_piece(d, *src.color, p, r);
    } else {
        eval(d, *src.sigma, v, r);
        sigma = r[0];
        eval(d, *src.color, v, r);
    }
    V g[3];  // ScalarMedium::classify, ShadeLanes, then apply_model
    for (int k = 0; k < 3; ++k) g[k] = src.associated ? r[k] : hn::Mul(r[k], sigma);
    if (shade != nullptr) {
        for (int c = 0; c < 3; ++c)
            g[c] = hn::Mul(exp_v::Fma(g[c], shade->diffuse[c], hn::Mul(sigma, shade->specular[c])),
                           shade->opacity);
        sigma = hn::Mul(sigma, shade->opacity);
    }
    if (src.model == Model::absorption)
        for (V& gk : g) gk = hn::Zero(d);
    const V sa = src.model == Model::emission ? hn::Zero(d) : sigma;
    const V x = hn::Mul(sa, dl);
    V weight;
    if (src.rule == PointRule::alpha) {
        const V alpha = exp_v::OneMinusExpNeg(d, x);
        weight = hn::IfThenElse(hn::Gt(sa, hn::Zero(d)), hn::Div(alpha, sa), dl);
        t = hn::Sub(one, alpha);
    } else {
        t = exp_v::ExpNeg(d, x);
        weight = dl;
    }
    for (int k = 0; k < 3; ++k) rad[k] = hn::Mul(g[k], weight);
    const M outside = hn::AndNot(zero, hn::Not(exp_v::InRange(d, x)));
    if (HWY_UNLIKELY(!hn::AllFalse(d, outside))) {  // ApplyRule's scalar lanes
        const std::size_t N = hn::Lanes(d);
        HWY_ALIGN double sl[8], dls[8], ts[8], gs[3][8], rs[3][8], om[8];
        hn::Store(sa, d, sl);
        hn::Store(dl, d, dls);
        hn::Store(t, d, ts);
        hn::Store(hn::IfThenElseZero(outside, one), d, om);
        for (int k = 0; k < 3; ++k) {
            hn::Store(g[k], d, gs[k]);
            hn::Store(rad[k], d, rs[k]);
        }
        for (std::size_t l = 0; l < N; ++l) {
            if (om[l] == 0.0) continue;
            const MediumSample m{sl[l], {gs[0][l], gs[1][l], gs[2][l]}};
            const Segment seg =
                src.rule == PointRule::alpha ? alpha_segment(m, dls[l]) : riemann_segment(m, dls[l]);
            ts[l] = seg.transmittance;
            for (int k = 0; k < 3; ++k) rs[k][l] = seg.radiance[k];
        }
        t = hn::Load(d, ts);
        for (int k = 0; k < 3; ++k) rad[k] = hn::Load(d, rs[k]);
    }
    t = hn::IfThenElse(zero, one, t);
    for (int k = 0; k < 3; ++k) rad[k] = hn::IfThenElseZero(hn::Not(zero), rad[k]);
}

/// The lanes of v whose bit is set in `bits` (the mask m's), stored in
/// order from `to` on; a whole vector is written (`to` has room past them).
HWY_INLINE void CompressLanes(D d, unsigned bits, M m, V v, double* to) {
#if HWY_TARGET <= HWY_AVX3
    static_cast<void>(d);
    static_cast<void>(m);
    _mm512_storeu_pd(to, _mm512_maskz_compress_pd(static_cast<__mmask8>(bits), v.raw));
#else
    static_cast<void>(bits);
    hn::CompressStore(v, m, d, to);
#endif
}

/// CompressLanes' inverse: the lanes whose bit is set in `bits` take
/// from[0], from[1], … in order, the others 0 (a whole vector is read).
HWY_INLINE V ExpandLanes(D d, unsigned bits, const double* from) {
#if HWY_TARGET <= HWY_AVX3
    static_cast<void>(d);
    return V{_mm512_maskz_expand_pd(static_cast<__mmask8>(bits), _mm512_loadu_pd(from))};
#else
    HWY_ALIGN double lanes_of[hn::MaxLanes(d)] = {};  // (all N written below)
    std::size_t k = 0;
    for (std::size_t i = 0; i < hn::Lanes(d); ++i) {
        const bool in = ((bits >> i) & 1u) != 0;
        lanes_of[i] = in ? from[k] : 0.0;
        k += in ? 1 : 0;
    }
    return hn::Load(d, lanes_of);
#endif
}

/// A packet's pre-integration (PacketPreint), per lane: its last end
/// (`prev`, at sample `last`; `has`: 1 once the ray has one), the last
/// sample its walk queued, and whether its ray stopped.
struct PreintLanes {
    static constexpr std::size_t L = kPacketLanesMax;
    HWY_ALIGN double prev[L];
    HWY_ALIGN double last[L];
    HWY_ALIGN double has[L];
    HWY_ALIGN double queued[L];
    HWY_ALIGN double stopped[L];  // 1: below the termination threshold
};

/// kExtra: the instantiation that also shades (src.shade: the point
/// rules' samples, or pre-integration's segments) and, point-sampled, keeps
/// each ray's depths (`depth`: DepthTrack's sums), each tested at run time;
/// the plain one does neither.
template <class T, bool kPre, bool kExtra>
void trace_packets_typed(const BatchSource& src, const PacketWalk& w, const PacketRay* rays,
                         std::size_t count, double termination, const double* bg, PacketResult* out,
                         const PacketPreint* pre, bool depth) {
    const D d;
    const std::size_t N = hn::Lanes(d), lanes = kPacketVectors * N;
    constexpr std::size_t K = kPacketVectors;
    PacketLanes L;
    PreintLanes P;
    std::size_t next = 0;
    // shaded: each lane's view, and its samples' places (pre-integrated:
    // each packed segment's midpoint and view, in `shading`)
    const bool shaded = kExtra && src.shade != nullptr;
    const Mat3* to_world = shaded ? &src.shade->index_to_world : nullptr;
    // with `depth`: each lane's DepthTrack sums (weighted, first)
    const bool tracked = kExtra && depth;
    auto load = [&](std::size_t l) {
        if (next < count) {
            L.load(l, rays + next, static_cast<std::int64_t>(next),
                   exits_are_sure(rays[next].dp, rays[next].delta, rays[next].A, rays[next].B, rays[next].p0,
                                  w.nodes),
                   to_world);
            if constexpr (kPre) L.n[l] += 1.0;  // ends 0..n: samples 1..n + 1
            ++next;
        } else {
            L.load(l, nullptr, -1, false, to_world);
        }
        P.prev[l] = P.last[l] = P.has[l] = P.queued[l] = P.stopped[l] = 0.0;
    };
    const V one = hn::Set(d, 1.0), thr = hn::Set(d, termination), e = hn::Set(d, src.zero_below);
    // Pre-integration: each step's segments, lane by lane (an end and the
    // one before it, consecutive samples of the ray; those across a gap
    // lie in empty macrocells that join, (1, 0)), the wanted ones (an end
    // at or above the zero range) packed into whole vectors in the order
    // (step, vector, sample, lane); `drain` pre-integrates the pack and
    // composites the steps in turn, a vector of lanes at a time (each
    // lane's segments in ray order, composite()'s operations, a lane's
    // until one leaves T below the threshold). The pack is drained at a
    // step's end once it holds kDrainAt segments, and before lanes finish.
    struct Step {
        std::uint8_t want[kSteps][kPacketVectors];  // the wanted segments' lanes
        std::uint16_t at[kSteps][kPacketVectors];   // the pack's place of the first
    };
    SegmentPack pack;
    constexpr int kDrainAt = 64;
    constexpr std::size_t kStepMost = kSteps * kPacketLanesMax;  // segments a step adds at most
    static_assert(kDrainAt + kStepMost <= SegmentPack::kCapacity);
    static_assert(SegmentPack::kPadded >= SegmentPack::kCapacity + 8);  // whole vectors read and written
    Step pending[kDrainAt + 1];
    std::size_t waiting = 0;  // steps in `pending`
    struct ShadingPack {      // shaded: the pack's segments' midpoints and views
        HWY_ALIGN double mid[3][SegmentPack::kPadded], view[3][SegmentPack::kPadded];
    };
    ShadingPack shading;
    struct DepthPack {  // tracked: the pack's segments' midpoints and starts along their rays
        HWY_ALIGN double mid[SegmentPack::kPadded], start[SegmentPack::kPadded];
    };
    DepthPack depths;
    // Shaded point samples: the segments of a step's samples that are not
    // below E, packed into whole vectors (their values, δ, points and
    // views), computed a vector at a time, and taken back lane by lane as
    // they composite
    constexpr std::size_t kPadded = kSteps * kPacketLanesMax + 8;  // whole vectors read and written
    struct StepSegments {
        HWY_ALIGN double v[kPadded], dl[kPadded], p[3][kPadded], view[3][kPadded];
        HWY_ALIGN double t[kPadded], rad[3][kPadded];
        std::uint8_t bits[kSteps][kPacketVectors];  // the packed samples' lanes
        std::uint16_t at[kSteps][kPacketVectors];   // the pack's place of the first
    };
    StepSegments step_segments;
    // integrate_preintegrated's shaded segments: the factors at each one's
    // midpoint a vector at a time (those the scalar code computes, from its
    // factors), then shade_segment, unless the segment is (1, 0)
    auto shade_pack = [&] {
        const ShadeSetup& sh = *src.shade;
        GridSampler<T> grid;  // x-fastest: shaded volumes are not in bricks
        grid.data = static_cast<const T*>(src.data);
        grid.nx = src.nx;
        grid.ny = src.ny;
        grid.nz = src.nz;
        for (std::size_t k0 = 0; k0 < static_cast<std::size_t>(pack.count); k0 += N) {
            const std::size_t in = std::min(N, static_cast<std::size_t>(pack.count) - k0);
            const M lanes_in = hn::FirstN(d, in);
            V pm[3], vw[3], fd[3], fs[3], fo;
            for (int a = 0; a < 3; ++a) {
                pm[a] = hn::IfThenElseZero(lanes_in, hn::Load(d, shading.mid[a] + k0));
                vw[a] = hn::IfThenElseZero(lanes_in, hn::Load(d, shading.view[a] + k0));
            }
            ShadeFactorsAt<T>(d, src, pm, vw, fd, fs, fo);
            HWY_ALIGN double sd[3][hn::MaxLanes(d)], ss[3][hn::MaxLanes(d)], so[hn::MaxLanes(d)];
            for (int c = 0; c < 3; ++c) {
                hn::Store(fd[c], d, sd[c]);
                hn::Store(fs[c], d, ss[c]);
            }
            hn::Store(fo, d, so);
            for (std::size_t l = 0; l < in; ++l) {
                const std::size_t k = k0 + l;
                Segment seg{pack.transmittance[k],
                            {pack.radiance[0][k], pack.radiance[1][k], pack.radiance[2][k]}};
                if (seg.transmittance == 1.0 && seg.radiance == Rgb{0, 0, 0}) continue;  // nothing to shade
                ShadeFactors sf;
                if (pack.scalar[k] != 0.0) {
                    const Vec3 p{shading.mid[0][k], shading.mid[1][k], shading.mid[2][k]};
                    sf = factors_of(sh, world_gradient(grid, p, sh.world_to_index),
                                    {shading.view[0][k], shading.view[1][k], shading.view[2][k]});
                } else {
                    for (int c = 0; c < 3; ++c) {
                        sf.diffuse[c] = sd[c][l];
                        sf.specular[c] = ss[c][l];
                    }
                    sf.opacity = so[l];
                }
                seg = shade_segment(seg, sf, pre->full);
                pack.transmittance[k] = seg.transmittance;
                for (int c = 0; c < 3; ++c) pack.radiance[c][k] = seg.radiance[c];
            }
        }
    };
    auto drain = [&] {
        if (waiting == 0) return;
        preintegrate_pack(src, pre->model, pre->full, pack);
        // (also those after a lane's ray stops: computed, not composited)
        for (int k = 0; k < pack.count; ++k)
            if (pack.scalar[k] != 0.0) {
                double t, r[3];
                pre->scalar(pre->ctx, pack.vf[k], pack.vb[k], pack.delta[k], &t, r);
                pack.transmittance[k] = t;
                for (int c = 0; c < 3; ++c) pack.radiance[c][k] = r[c];
            }
        if (shaded) shade_pack();
        for (std::size_t h = 0; h < K; ++h) {
            const std::size_t o = h * N;
            V tr = hn::Load(d, L.T + o), C[3];
            for (int c = 0; c < 3; ++c) C[c] = hn::Load(d, L.C[c] + o);
            M stopped = hn::Eq(hn::Load(d, P.stopped + o), one);
            V weighted = hn::Zero(d), first = hn::Zero(d);
            if (tracked) {
                weighted = hn::Load(d, L.weighted + o);
                first = hn::Load(d, L.first + o);
            }
            for (std::size_t st = 0; st < waiting; ++st)
                for (std::size_t q = 0; q < kSteps; ++q) {
                    const unsigned bits = pending[st].want[q][h];
                    if (bits == 0) continue;
                    const std::size_t at = pending[st].at[q][h];
                    V t, r[3];
                    const std::uint8_t b8 = static_cast<std::uint8_t>(bits);
                    auto expand = [&](const double* from) { return ExpandLanes(d, bits, from + at); };
#if HWY_TARGET <= HWY_AVX3
                    t = V{_mm512_mask_expand_pd(one.raw, static_cast<__mmask8>(bits),
                                                _mm512_loadu_pd(pack.transmittance + at))};
#else
                    t = hn::IfThenElse(hn::LoadMaskBits(d, &b8), expand(pack.transmittance), one);
#endif
                    for (int c = 0; c < 3; ++c) r[c] = expand(pack.radiance[c]);
                    const M active = hn::AndNot(stopped, hn::LoadMaskBits(d, &b8));
                    for (int c = 0; c < 3; ++c)
                        C[c] = hn::IfThenElse(active, hn::Add(C[c], hn::Mul(tr, r[c])), C[c]);
                    if (tracked) {  // DepthTrack::add(i, 1 − t, T before)
                        const V mid = expand(depths.mid), start = expand(depths.start);
                        const V alpha = hn::Sub(one, t);
                        const M hit = hn::And(active, hn::Gt(alpha, hn::Zero(d)));
                        weighted = hn::IfThenElse(hit, hn::Add(weighted, hn::Mul(hn::Mul(tr, alpha), mid)),
                                                  weighted);
                        first = hn::IfThenElse(hn::And(hit, hn::Lt(start, first)), start, first);
                    }
                    tr = hn::IfThenElse(active, hn::Mul(tr, t), tr);
                    stopped = hn::Or(stopped, hn::And(active, hn::Lt(tr, thr)));
                }
            hn::Store(tr, d, L.T + o);
            for (int c = 0; c < 3; ++c) hn::Store(C[c], d, L.C[c] + o);
            hn::Store(hn::IfThenElseZero(stopped, one), d, P.stopped + o);
            if (tracked) {
                hn::Store(weighted, d, L.weighted + o);
                hn::Store(first, d, L.first + o);
            }
        }
        waiting = 0;
        pack.count = 0;
    };
    for (std::size_t l = 0; l < lanes; ++l) load(l);
    const bool shared = shared_pieces(src);
    const bool pairs = gathers_pairs<T>(src);  // then prefetched, row by row
    const std::array<std::int64_t, 4> rows = corner_rows<T>(src);
    HWY_ALIGN double cell[kSteps][kPacketGroups][3][kBatch];
    HWY_ALIGN double frac[kSteps][kPacketGroups][3][kBatch];
    HWY_ALIGN double values[kSteps][kPacketGroups * kBatch];
    // The lanes whose bit is set in `done` finish: their results, with the
    // background where the ray went through (eq. (10)); then the next rays.
    auto finish = [&](const M* done, bool background) {
        HWY_ALIGN double mask[kPacketLanesMax];
        for (std::size_t h = 0; h < K; ++h) hn::Store(hn::IfThenElseZero(done[h], one), d, mask + h * N);
        if constexpr (kPre) drain();
        for (std::size_t l = 0; l < lanes; ++l) {
            if (mask[l] == 0.0) continue;
            bool with_bg = background;
            if constexpr (kPre) with_bg = with_bg && P.stopped[l] == 0.0;
            PacketResult& r = out[L.ray[l]];
            const double tl = L.T[l];
            for (int c = 0; c < 3; ++c) r.radiance[c] = with_bg ? L.C[c][l] + tl * bg[c] : L.C[c][l];
            r.alpha = 1.0 - tl;
            if (tracked) {  // DepthTrack::finish
                r.depth = r.alpha > 0.0 ? L.weighted[l] / r.alpha : INFINITY;
                r.first_hit = L.first[l];
            }
            load(l);
        }
    };
    M live[K], mask[K];
    for (;;) {
        // Lanes past their run take the next one; the walk runs one run
        // ahead of the samples, for every lane that has none, whenever a
        // lane needs one, so that its vectors serve several lanes.
        for (;;) {
            bool urgent = false;
            for (std::size_t h = 0; h < K; ++h) {
                const std::size_t o = h * N;
                live[h] = hn::Eq(hn::Load(d, L.live + o), one);
                const V i = hn::Load(d, L.i + o), re = hn::Load(d, L.run_end + o);
                V qs[kPacketQueue], qe[kPacketQueue];
                for (std::size_t q = 0; q < kPacketQueue; ++q) {
                    qs[q] = hn::Load(d, L.next_start[q] + o);
                    qe[q] = hn::Load(d, L.next_end[q] + o);
                }
                const M ended = hn::And(live[h], hn::Gt(i, re));
                const M has_next = hn::Le(qs[0], qe[0]);
                const M take = hn::And(ended, has_next);
                hn::Store(hn::IfThenElse(take, qs[0], i), d, L.i + o);
                TakeQueuedRun(d, L, o, take, re, qs, qe);
                const M walking = hn::And(live[h], hn::Le(hn::Load(d, L.w + o), hn::Load(d, L.n + o)));
                urgent = urgent || !hn::AllFalse(d, hn::AndNot(has_next, hn::And(ended, walking)));
                // every lane whose queue has room
                mask[h] = hn::AndNot(hn::Le(qs[kPacketQueue - 1], qe[kPacketQueue - 1]), walking);
            }
            if (!urgent) break;
            for (std::size_t h = 0; h < K; ++h)
                if (!hn::AllFalse(d, mask[h])) WalkLanes(d, w, L, h * N, mask[h], kPre ? P.queued : nullptr);
        }
        // lanes past their last run: finished
        bool any_live = false, through = false;
        for (std::size_t h = 0; h < K; ++h) {
            mask[h] = hn::And(live[h], hn::Gt(hn::Load(d, L.i + h * N), hn::Load(d, L.run_end + h * N)));
            any_live = any_live || !hn::AllFalse(d, live[h]);
            through = through || !hn::AllFalse(d, mask[h]);
        }
        if (!any_live) return;
        if (through) {
            finish(mask, true);
            continue;
        }
        // up to kSteps samples per lane, i, i + 1, … to the run's end, then on
        // from the start of the next run in its queue (the empty run between
        // gives (1, 0)); in ray order, so compositing them in turn is the
        // one-by-one sum
        M more_of[kSteps][K];
        // how many samples each lane takes, and (pre-integration) which
        HWY_ALIGN double sampled[kPacketLanesMax], sample_at[kSteps][kPacketLanesMax];
        V left[K];  // run_end − i: the samples of the current run after the next one
        for (std::size_t h = 0; h < K; ++h) {
            const V i = hn::Load(d, L.i + h * N), re = hn::Load(d, L.run_end + h * N);
            const V ns = hn::Load(d, L.next_start[0] + h * N), ne = hn::Load(d, L.next_end[0] + h * N);
            left[h] = hn::Sub(re, i);
            const std::size_t g = h * N / kBatch, b = h * N % kBatch;
            V steps = hn::Zero(d);
            for (std::size_t q = 0; q < kSteps; ++q) {
                V p[3];
                const V qq = hn::Set(d, static_cast<double>(q));
                const M here = hn::Le(qq, left[h]);
                // past the run's end: on into the next run found
                const V jn = hn::Add(ns, hn::Sub(hn::Sub(qq, left[h]), one));
                const V j = hn::IfThenElse(here, hn::Add(i, qq), jn);
                more_of[q][h] = hn::And(live[h], hn::Or(here, hn::Le(jn, ne)));
                steps = hn::IfThenElse(more_of[q][h], hn::Add(steps, one), steps);
                if constexpr (kPre || kExtra) hn::Store(j, d, sample_at[q] + h * N);
                LanePositions(d, L, h * N, j, p);
                for (int a = 0; a < 3; ++a) locate(d, src, a, p[a], b, cell[q][g], frac[q][g]);
            }
            hn::Store(steps, d, sampled + h * N);
            if (pairs) {  // the corner rows of each lane's cell kPrefetchAhead samples on
                V p[3];
                LanePositions(d, L, h * N, hn::Add(i, hn::Set(d, static_cast<double>(kPrefetchAhead))), p);
                HWY_ALIGN double pc[3][kBatch], pf[3][kBatch];
                for (int a = 0; a < 3; ++a) locate(d, src, a, p[a], 0, pc, pf);
                HWY_ALIGN std::int64_t at[8];
                if constexpr (std::is_same_v<T, float>) {  // offsets may pass 2³¹
                    const hn::Rebind<std::int64_t, D> dl;
                    hn::Store(hn::ConvertTo(dl, cell_bytes<T>(d, src, pc, 0)), dl, at);
                } else {
                    const hn::Rebind<std::int32_t, D> di;
                    const hn::Rebind<std::int64_t, D> dl;
                    hn::Store(hn::PromoteTo(dl, cell_offsets<T>(di, src, pc, 0)), dl, at);
                }
                for (std::size_t l = 0; l < N; ++l) {
                    const char* q0 = static_cast<const char*>(src.data) + at[l];
                    for (const std::int64_t r : rows) __builtin_prefetch(q0 + r);
                }
            }
        }
        for (std::size_t g = 0; g * kBatch < lanes; ++g)
            for (std::size_t q = 0; q < kSteps; ++q)
                trilinear<T>(src, cell[q][g], frac[q][g], 0,
                             std::min<std::size_t>(kBatch, lanes - g * kBatch), values[q] + g * kBatch,
                             false);
        if constexpr (kPre) {  // the step's segments into the pack
            Step& rec = pending[waiting];
            int k = pack.count;
            for (std::size_t h = 0; h < K; ++h) {
                const std::size_t o = h * N;
                const M go = hn::AndNot(hn::Eq(hn::Load(d, P.stopped + o), one), live[h]);
                V vf = hn::Load(d, P.prev + o), jl = hn::Load(d, P.last + o);
                M has = hn::Eq(hn::Load(d, P.has + o), one);
                const V dl = hn::Load(d, L.dl + o);
                for (std::size_t q = 0; q < kSteps; ++q) {
                    const M take = hn::And(more_of[q][h], go);  // a prefix of the step's samples
                    const V vb = hn::Load(d, values[q] + o), j = hn::Load(d, sample_at[q] + o);
                    const M seg = hn::And(take, hn::And(has, hn::Eq(j, hn::Add(jl, one))));
                    const M want = hn::AndNot(hn::And(hn::Lt(vf, e), hn::Lt(vb, e)), seg);
                    std::uint8_t bits[8] = {};
                    hn::StoreMaskBits(d, want, bits);
                    rec.want[q][h] = bits[0];
                    rec.at[q][h] = static_cast<std::uint16_t>(k);
                    if (bits[0] != 0) {
                        // the wanted lanes to the front, a whole vector stored
                        // (the pack's padding takes the rest)
                        auto compress = [&](V v, double* to) { CompressLanes(d, bits[0], want, v, to); };
                        compress(vf, pack.vf + k);
                        compress(vb, pack.vb + k);
                        compress(dl, pack.delta + k);
                        if (kExtra && shaded) {  // segment j − 1's midpoint: t_near + (j − 1.5)·δ
                            V pm[3];
                            LanePositions(d, L, o, hn::Sub(j, hn::Set(d, 0.5)), pm);
                            for (int a = 0; a < 3; ++a) {
                                compress(pm[a], shading.mid[a] + k);
                                compress(hn::Load(d, L.view[a] + o), shading.view[a] + k);
                            }
                        }
                        if (tracked) {  // segment j − 1: its midpoint t_near + (j − 1.5)·δ, its start
                            const V tn = hn::Load(d, L.tn + o);
                            compress(hn::Add(tn, hn::Mul(hn::Sub(j, hn::Set(d, 1.5)), dl)), depths.mid + k);
                            compress(hn::Add(tn, hn::Mul(hn::Sub(j, hn::Set(d, 2.0)), dl)), depths.start + k);
                        }
                        k += std::popcount(static_cast<unsigned>(bits[0]));
                    }
                    vf = hn::IfThenElse(take, vb, vf);
                    jl = hn::IfThenElse(take, j, jl);
                    has = hn::Or(has, take);
                }
                hn::Store(vf, d, P.prev + o);
                hn::Store(jl, d, P.last + o);
                hn::Store(hn::IfThenElseZero(has, one), d, P.has + o);
            }
            if (k > pack.count) {
                pack.count = k;
                ++waiting;
            }
            // drained once it holds kDrainAt segments (8 vectors) rather
            // than at every step, its vectors fuller; a lane whose ray
            // stops in a waiting step samples on until then, its later
            // segments not composited (the same sums)
            if (pack.count >= kDrainAt) drain();
        }
        if (!kPre && shaded) {
            // The samples the compositing below may take: those not below E
            // that the lanes take (those after a ray stops too). Their
            // shading factors (ShadeFactorsAt) and segments are computed lane
            // by lane, so in the pack's vectors they are the bits the lanes'
            // own vectors gave, with fewer idle lanes (a step's vectors that
            // hold such samples hold 2.7 of 8 on the chest CT's bone frame,
            // 3.8 on the bunny's). Unshaded frames compute their segments in
            // the lanes' vectors: packing them measured 0.95× on the bunny's
            // dense `ct-soft-tissue` frame for 1.02–1.04× on the bone frames.
            StepSegments& sp = step_segments;
            std::size_t k = 0;
            for (std::size_t h = 0; h < K; ++h) {
                const std::size_t o = h * N;
                for (std::size_t q = 0; q < kSteps; ++q) {
                    const V v = hn::Load(d, values[q] + o);
                    const M take = hn::AndNot(hn::Lt(v, e), more_of[q][h]);
                    std::uint8_t bits[8] = {};
                    hn::StoreMaskBits(d, take, bits);
                    sp.bits[q][h] = bits[0];
                    sp.at[q][h] = static_cast<std::uint16_t>(k);
                    if (bits[0] == 0) continue;
                    CompressLanes(d, bits[0], take, v, sp.v + k);
                    CompressLanes(d, bits[0], take, hn::Load(d, L.dl + o), sp.dl + k);
                    V p[3];
                    LanePositions(d, L, o, hn::Load(d, sample_at[q] + o), p);
                    for (int a = 0; a < 3; ++a) {
                        CompressLanes(d, bits[0], take, p[a], sp.p[a] + k);
                        CompressLanes(d, bits[0], take, hn::Load(d, L.view[a] + o), sp.view[a] + k);
                    }
                    k += static_cast<std::size_t>(std::popcount(static_cast<unsigned>(bits[0])));
                }
            }
            for (std::size_t k0 = 0; k0 < k; k0 += N) {
                // the lanes past the last repeat the first sample
                const M in = hn::FirstN(d, k - k0);
                auto packed = [&](const double* from) {
                    return hn::IfThenElse(in, hn::Load(d, from + k0), hn::Set(d, from[k0]));
                };
                V pm[3], vw[3];
                for (int a = 0; a < 3; ++a) {
                    pm[a] = packed(sp.p[a]);
                    vw[a] = packed(sp.view[a]);
                }
                LaneShade f;
                ShadeFactorsAt<T>(d, src, pm, vw, f.diffuse, f.specular, f.opacity);
                V t, rad[3];
                LaneSegments(d, src, shared, packed(sp.v), packed(sp.dl), hn::Not(in), &f, t, rad);
                hn::Store(t, d, sp.t + k0);
                for (int c = 0; c < 3; ++c) hn::Store(rad[c], d, sp.rad[c] + k0);
            }
        }
        bool stop = false;
        for (std::size_t h = 0; h < K; ++h) {
            const std::size_t o = h * N;
            if constexpr (kPre) {
                mask[h] = hn::And(live[h], hn::Eq(hn::Load(d, P.stopped + o), one));
            } else {
                const V dl = hn::Load(d, L.dl + o);
                V tr = hn::Load(d, L.T + o);
                V C[3];
                for (int k = 0; k < 3; ++k) C[k] = hn::Load(d, L.C[k] + o);
                V weighted = hn::Zero(d), first = hn::Zero(d);
                if constexpr (kExtra) {
                    if (tracked) {
                        weighted = hn::Load(d, L.weighted + o);
                        first = hn::Load(d, L.first + o);
                    }
                }
                for (std::size_t q = 0; q < kSteps; ++q) {
                    // sample q, unless the run has no more or an earlier one stopped the ray
                    const M more = q == 0 ? more_of[0][h] : hn::AndNot(hn::Lt(tr, thr), more_of[q][h]);
                    const M zero = hn::Or(hn::Lt(hn::Load(d, values[q] + o), e), hn::Not(more));
                    if (hn::AllTrue(d, zero)) continue;
                    V t, rad[3];
                    if (shaded) {  // the step's packed segments, back in the lanes: (1, 0) where `zero`
                        const StepSegments& sp = step_segments;
                        const unsigned bits = sp.bits[q][h];
                        const std::size_t at = sp.at[q][h];
                        t = hn::IfThenElse(zero, one, ExpandLanes(d, bits, sp.t + at));
                        for (int c = 0; c < 3; ++c)
                            rad[c] = hn::IfThenElseZero(hn::Not(zero), ExpandLanes(d, bits, sp.rad[c] + at));
                    } else {
                        LaneSegments(d, src, shared, hn::Load(d, values[q] + o), dl, zero, nullptr, t, rad);
                    }
                    if constexpr (kExtra) {
                        if (tracked) {  // DepthTrack::add(j, 1 − t, T before)
                            const V j = hn::Load(d, sample_at[q] + o), tn = hn::Load(d, L.tn + o);
                            const V alpha = hn::Sub(one, t);
                            const M hit = hn::Gt(alpha, hn::Zero(d));
                            const V mid = hn::Add(tn, hn::Mul(hn::Sub(j, hn::Set(d, 0.5)), dl));
                            weighted = hn::IfThenElse(
                                hit, hn::Add(weighted, hn::Mul(hn::Mul(tr, alpha), mid)), weighted);
                            const V start = hn::Add(tn, hn::Mul(hn::Sub(j, one), dl));
                            first = hn::IfThenElse(hn::And(hit, hn::Lt(start, first)), start, first);
                        }
                    }
                    // composite (eq. (10)): the zero lanes' (1, 0) leave both unchanged
                    for (int k = 0; k < 3; ++k) C[k] = hn::Add(C[k], hn::Mul(tr, rad[k]));
                    tr = hn::Mul(tr, t);
                }
                for (int k = 0; k < 3; ++k) hn::Store(C[k], d, L.C[k] + o);
                hn::Store(tr, d, L.T + o);
                if (tracked) {
                    hn::Store(weighted, d, L.weighted + o);
                    hn::Store(first, d, L.first + o);
                }
                mask[h] = hn::And(live[h], hn::Lt(tr, thr));
            }
            const V taken = hn::Load(d, sampled + o);
            const V i = hn::Load(d, L.i + o);
            // into the next run: it becomes the current one
            const M into = hn::And(live[h], hn::Gt(taken, hn::Add(left[h], one)));
            V qs[kPacketQueue], qe[kPacketQueue];
            for (std::size_t q = 0; q < kPacketQueue; ++q) {
                qs[q] = hn::Load(d, L.next_start[q] + o);
                qe[q] = hn::Load(d, L.next_end[q] + o);
            }
            hn::Store(hn::IfThenElse(into, hn::Add(qs[0], hn::Sub(hn::Sub(taken, left[h]), one)),
                                     hn::Add(i, taken)),
                      d, L.i + o);
            TakeQueuedRun(d, L, o, into, hn::Load(d, L.run_end + o), qs, qe);
            stop = stop || !hn::AllFalse(d, mask[h]);
        }
        if (stop) finish(mask, false);
    }
}

void PreparePacketRays(const PacketFrame& f, const PacketRaysIn& in, PacketRay* out, int* octant,
                       std::uint8_t* meets) {
    const D d;
    const std::size_t N = hn::Lanes(d);
    const V zero = hn::Zero(d), one = hn::Set(d, 1.0), inf = hn::Set(d, INFINITY);
    const V h = hn::Set(d, f.h), offset = hn::Set(d, f.offset);
    const V limit = hn::Set(d, 0x1p52), never = hn::Set(d, 0x1p60);
    for (std::size_t b = 0; b < in.count; b += N) {
        // whole vectors: the lanes past the last ray repeat it
        HWY_ALIGN double lane[8][8];
        for (std::size_t l = 0; l < N; ++l) {
            const std::size_t k = std::min(b + l, in.count - 1);
            for (int a = 0; a < 3; ++a) {
                lane[a][l] = in.origin[a][k];
                lane[3 + a][l] = in.dir[a][k];
            }
            lane[6][l] = in.lo[k];
            lane[7][l] = in.hi[k];
        }
        // Renderer::Impl::span_of: p0 = M·(origin − the lattice's origin), dp = M·dir
        V v[3], dir[3], p0[3], dp[3];
        for (int a = 0; a < 3; ++a) {
            v[a] = hn::Sub(hn::Load(d, lane[a]), hn::Set(d, f.origin[a]));
            dir[a] = hn::Load(d, lane[3 + a]);
        }
        for (int r = 0; r < 3; ++r) {
            auto row = [&](const V* x) {  // Mat3 · Vec3, in its order
                return hn::Add(hn::Add(hn::Mul(hn::Set(d, f.world_to_index[r][0]), x[0]),
                                       hn::Mul(hn::Set(d, f.world_to_index[r][1]), x[1])),
                               hn::Mul(hn::Set(d, f.world_to_index[r][2]), x[2]));
            };
            p0[r] = row(v);
            dp[r] = row(dir);
        }
        // intersect_box
        V t0 = zero, t1 = inf;
        M ok = hn::FirstN(d, N);
        for (int a = 0; a < 3; ++a) {
            const V hi = hn::Set(d, f.node_hi[a]);
            const M flat = hn::Eq(dp[a], zero);
            ok = hn::AndNot(hn::And(flat, hn::Or(hn::Lt(p0[a], zero), hn::Gt(p0[a], hi))), ok);
            const V ta = hn::Div(hn::Sub(zero, p0[a]), dp[a]), tb = hn::Div(hn::Sub(hi, p0[a]), dp[a]);
            const M swap = hn::Gt(ta, tb);
            const V near = hn::IfThenElse(swap, tb, ta), far = hn::IfThenElse(swap, ta, tb);
            t0 = hn::IfThenElse(hn::AndNot(flat, hn::Lt(t0, near)), near, t0);  // std::max(t0, ta)
            t1 = hn::IfThenElse(hn::AndNot(flat, hn::Lt(far, t1)), far, t1);    // std::min(t1, tb)
        }
        ok = hn::And(ok, hn::Gt(t1, t0));
        // segment_count and δ
        const V length = hn::Sub(t1, t0);
        const V n = hn::Max(one, hn::Ceil(hn::Div(length, h)));
        const V delta = hn::Div(length, n);
        // RunFinder: the forward axes, and the samples before and after the
        // pixel bounds (first = 1)
        V A[3], B[3];
        for (int a = 0; a < 3; ++a) {
            const V inv = hn::Div(one, hn::Mul(dp[a], delta));
            const M crosses = hn::IsFinite(inv);
            A[a] = hn::IfThenElseZero(crosses, inv);
            B[a] = hn::IfThenElse(
                crosses,
                hn::Add(hn::Sub(hn::Div(hn::Sub(hn::Div(hn::Neg(p0[a]), dp[a]), t0), delta), offset), one),
                inf);
        }
        auto index_at = [&](V t) {
            const V x = hn::Add(hn::Sub(hn::Div(hn::Sub(t, t0), delta), offset), one);
            return hn::Min(hn::Max(x, hn::Neg(limit)), limit);
        };
        const V lo = hn::Load(d, lane[6]), hi = hn::Load(d, lane[7]);
        const V before =
            hn::IfThenElse(hn::Gt(lo, hn::Neg(inf)), hn::Sub(hn::Floor(index_at(lo)), one), hn::Neg(never));
        const V after = hn::IfThenElse(hn::Lt(hi, inf), hn::Add(hn::Ceil(index_at(hi)), one), never);
        HWY_ALIGN double o[18][8];
        for (int a = 0; a < 3; ++a) {
            hn::Store(p0[a], d, o[a]);
            hn::Store(dp[a], d, o[3 + a]);
            hn::Store(A[a], d, o[6 + a]);
            hn::Store(B[a], d, o[9 + a]);
        }
        hn::Store(t0, d, o[12]);
        hn::Store(delta, d, o[13]);
        hn::Store(n, d, o[14]);
        hn::Store(hn::IfThenElseZero(ok, one), d, o[15]);
        hn::Store(before, d, o[16]);
        hn::Store(after, d, o[17]);
        for (std::size_t l = 0; l < N && b + l < in.count; ++l) {
            PacketRay& r = out[b + l];
            int oct = 0;
            for (int a = 0; a < 3; ++a) {
                r.p0[a] = o[a][l];
                r.dp[a] = o[3 + a][l];
                r.A[a] = o[6 + a][l];
                r.B[a] = o[9 + a][l];
                if (o[3 + a][l] < 0.0) oct |= 1 << a;
            }
            r.t_near = o[12][l];
            r.delta = o[13][l];
            r.n = o[14][l];
            r.offset = f.offset;
            r.before = o[16][l];
            r.after = o[17][l];
            octant[b + l] = oct;
            meets[b + l] = o[15][l] != 0.0 ? 1 : 0;
        }
    }
}

void TracePackets(const BatchSource& src, const PacketWalk& w, const PacketRay* rays, std::size_t count,
                  double termination, const double* bg, PacketResult* out, const PacketPreint* pre,
                  bool depth) {
    visit_dtype(src.type, [&]<class T>(T*) {
        if (pre != nullptr && (src.shade != nullptr || depth))
            trace_packets_typed<T, true, true>(src, w, rays, count, termination, bg, out, pre, depth);
        else if (pre != nullptr)
            trace_packets_typed<T, true, false>(src, w, rays, count, termination, bg, out, pre, false);
        else if (src.shade != nullptr || depth)
            trace_packets_typed<T, false, true>(src, w, rays, count, termination, bg, out, nullptr, depth);
        else
            trace_packets_typed<T, false, false>(src, w, rays, count, termination, bg, out, nullptr, false);
    });
}

void ClassifyBatch(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, BatchOut& out) {
    visit_dtype(src.type, [&]<class T>(T*) { classify_typed<T>(src, ray, j0, count, out); });
}

void ShadeBatchAt(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, std::uint32_t skip,
                  ShadeBatch& out) {
    const D d;
    const std::size_t N = hn::Lanes(d);
    visit_dtype(src.type, [&]<class T>(T*) {
        for (std::size_t b = 0; b < static_cast<std::size_t>(count); b += N) {
            const std::uint32_t lanes = ((1u << N) - 1u) << b;
            if ((skip & lanes) == lanes) continue;
            V diffuse[3], specular[3], opacity;
            ShadeFactorsLanes<T>(d, src, ray, j0, b, diffuse, specular, opacity);
            for (int c = 0; c < 3; ++c) {
                hn::Store(diffuse[c], d, out.diffuse[c] + b);
                hn::Store(specular[c], d, out.specular[c] + b);
            }
            hn::Store(opacity, d, out.opacity + b);
        }
    });
}

void InterpolateBatch(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, double* out,
                      std::uint64_t* below) {
    std::size_t used = 0;  // values written: whole vectors
    visit_dtype(src.type, [&]<class T>(T*) {
        for (int c = 0; c < count; c += kBatch)
            used = static_cast<std::size_t>(c) +
                   interpolate_typed<T>(src, ray, j0 + c, std::min(count - c, kBatch), out + c);
    });
    if (below == nullptr) return;
    const D d;
    const V zero_below = hn::Set(d, src.zero_below);
    std::uint64_t bits = 0;
    for (std::size_t b = 0; b < used; b += hn::Lanes(d)) {
        std::uint8_t lanes[8] = {};
        hn::StoreMaskBits(d, hn::Lt(hn::Load(d, out + b), zero_below), lanes);  // N ≤ 8 lanes of doubles
        bits |= static_cast<std::uint64_t>(lanes[0]) << b;
    }
    *below = bits & ((std::uint64_t{1} << count) - 1u);  // count < 64
}

std::int64_t TargetOf() {
    return HWY_TARGET;
}

bool FusedOf() {
    return exp_v::kFused;
}

// NOLINTNEXTLINE(google-readability-namespace-comments)
}  // namespace HWY_NAMESPACE
}  // namespace fathom::simd
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fathom::simd {

HWY_EXPORT(ClassifyBatch);
HWY_EXPORT(InterpolateBatch);
HWY_EXPORT(ShadeBatchAt);
HWY_EXPORT(TargetOf);
HWY_EXPORT(FusedOf);
HWY_EXPORT(TracePackets);
HWY_EXPORT(PreparePacketRays);

void classify_batch(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, BatchOut& out) {
    HWY_DYNAMIC_DISPATCH(ClassifyBatch)(src, ray, j0, count, out);
}

void interpolate_batch(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, double* out,
                       std::uint64_t* below) {
    HWY_DYNAMIC_DISPATCH(InterpolateBatch)(src, ray, j0, count, out, below);
}

void trace_packets(const BatchSource& src, const PacketWalk& walk, const PacketRay* rays, std::size_t count,
                   double termination, const double* bg, PacketResult* out, const PacketPreint* pre,
                   bool depth) {
    HWY_DYNAMIC_DISPATCH(TracePackets)(src, walk, rays, count, termination, bg, out, pre, depth);
}

void prepare_packet_rays(const PacketFrame& frame, const PacketRaysIn& in, PacketRay* out, int* octant,
                         std::uint8_t* meets) {
    HWY_DYNAMIC_DISPATCH(PreparePacketRays)(frame, in, out, octant, meets);
}

void shade_batch(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, std::uint32_t skip,
                 ShadeBatch& out) {
    HWY_DYNAMIC_DISPATCH(ShadeBatchAt)(src, ray, j0, count, skip, out);
}

namespace {
FlatFunction flatten_any(const std::vector<double>& knots, const std::vector<double>& inv, int components,
                         auto&& value) {
    FlatFunction f;
    f.knots = knots;
    f.inv = inv;
    f.components = components;
    for (int c = 0; c < components; ++c)
        for (std::size_t i = 0; i < knots.size(); ++i) f.y[c].push_back(value(i, c));
    if (!knots.empty() && knots.size() <= FlatFunction::kTable)
        for (std::size_t i = 0; i < FlatFunction::kTable; ++i) {
            const std::size_t k = std::min(i, knots.size() - 1);
            f.table[0][i] = knots[k];
            for (int c = 0; c < components; ++c) f.table[1 + c][i] = f.y[c][k];
            f.table[FlatFunction::kInvRow][i] = inv[k];
        }
    return f;
}
}  // namespace

FlatFunction flatten(const PiecewiseLinear<1>& f) {
    return flatten_any(f.knots(), f.inverse_widths(), 1,
                       [&](std::size_t i, int) { return f.values()[i][0]; });
}

FlatFunction flatten(const PiecewiseLinear<3>& f) {
    return flatten_any(f.knots(), f.inverse_widths(), 3,
                       [&](std::size_t i, int c) { return f.values()[i][static_cast<std::size_t>(c)]; });
}

std::vector<std::uint32_t> active_cells(const Volume& v, double e, int threads) {
    std::vector<std::uint32_t> bits;
    const auto& n = v.dims();
    const std::int64_t bx = n[0] / 2, by = n[1] / 2, bz = n[2] / 2;  // blocks: ⌈(n − 1)/2⌉
    if (v.components() != 1 || n[0] * n[1] * n[2] >= (std::int64_t{1} << 31)) return bits;
    visit_dtype(v.dtype(), [&]<class T>(T*) {
        if constexpr (kPairs<T>) {
            const T* data = v.data<T>();
            // integers: !(v < e) ⇔ v ≥ ⌈e⌉ (e finite), compared in T: a
            // threshold above T's range is never reached, one below always
            const double at_least = std::ceil(e);
            // or's reaches(row[x]) into col[x] for x < count (local pointers: no reloads)
            auto mark = [&](const T* row, std::uint8_t* col, std::int64_t count) {
                if constexpr (std::is_integral_v<T>) {
                    if (!(at_least <= static_cast<double>(std::numeric_limits<T>::max())))
                        return;  // NaN: never
                    const T t = at_least <= static_cast<double>(std::numeric_limits<T>::lowest())
                                    ? std::numeric_limits<T>::lowest()
                                    : static_cast<T>(at_least);
                    for (std::int64_t x = 0; x < count; ++x) col[x] |= static_cast<std::uint8_t>(row[x] >= t);
                } else {
                    const double ed = e;
                    for (std::int64_t x = 0; x < count; ++x)
                        col[x] |= static_cast<std::uint8_t>(!(static_cast<double>(row[x]) < ed));
                }
            };
            bits.assign(static_cast<std::size_t>(bx * by * bz / 32 + 2), 0u);  // a word to spare for gathers
            // Block rows (j, k) in one contiguous range per thread, with one
            // column buffer each; a word may span two rows: one atomic or per word.
            std::vector<std::vector<std::uint8_t>> cols(static_cast<std::size_t>(resolve_threads(threads)));
            auto block_row = [&](std::int64_t row_index, std::vector<std::uint8_t>& col) {
                const std::int64_t j = row_index % by, k = row_index / by;
                // col[x]: some node of rows y = 2j … 2j + 2, z = 2k … 2k + 2 at x is not below e
                col.assign(static_cast<std::size_t>(n[0]), 0);
                for (std::int64_t z = 2 * k; z <= std::min(2 * k + 2, n[2] - 1); ++z)
                    for (std::int64_t y = 2 * j; y <= std::min(2 * j + 2, n[1] - 1); ++y) {
                        mark(data + n[0] * (y + n[1] * z), col.data(), n[0]);
                    }
                const std::int64_t base = bx * row_index;  // block (0, j, k)
                std::int64_t word = base >> 5;
                std::uint32_t acc = 0;
                auto flush = [&] {
                    if (acc != 0)
                        std::atomic_ref<std::uint32_t>(bits[static_cast<std::size_t>(word)])
                            .fetch_or(acc, std::memory_order_relaxed);
                    acc = 0;
                };
                for (std::int64_t i = 0; i < bx; ++i) {  // block i: nodes x = 2i … 2i + 2
                    const std::int64_t b = base + i;
                    if ((b >> 5) != word) {
                        flush();
                        word = b >> 5;
                    }
                    const auto* c = col.data() + 2 * i;
                    if ((c[0] | c[1] | (2 * i + 2 < n[0] ? c[2] : 0)) != 0) acc |= 1u << (b & 31);
                }
                flush();
            };
            parallel_blocks(static_cast<std::size_t>(by * bz), static_cast<int>(cols.size()),
                            [&](std::size_t r0, std::size_t r1, int t) {
                                for (std::size_t r = r0; r < r1; ++r)
                                    block_row(static_cast<std::int64_t>(r),
                                              cols[static_cast<std::size_t>(t)]);
                            });
        }
    });
    return bits;
}

std::string active_target() {
    return hwy::TargetName(HWY_DYNAMIC_DISPATCH(TargetOf)());
}

bool fused_lanes() {
    return HWY_DYNAMIC_DISPATCH(FusedOf)();
}

std::vector<std::int64_t> available_targets() {
    std::vector<std::int64_t> r;
    const std::int64_t supported = hwy::SupportedTargets();
    for (std::int64_t t : hwy::SupportedAndGeneratedTargets())
        if ((t & supported) != 0) r.push_back(t);
    return r;
}

void force_target(std::int64_t target) {
    hwy::SetSupportedTargetsForTest(target);
    hwy::GetChosenTarget().Update(hwy::SupportedTargets());
}

}  // namespace fathom::simd
#endif
