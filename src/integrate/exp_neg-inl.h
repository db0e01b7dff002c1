// exp_neg.h's e^{−x} and 1 − e^{−x} per SIMD lane, for the Highway
// translation units (simd_classify.cpp, simd_preint.cpp), with Fma, the
// multiply–add those kernels fuse, and a transfer function's position on
// its piece: every lane performs the scalar
// functions' operations in their order, a product and the sum that takes it
// fused into one rounding where Fma fuses (targets with FMA, built with
// FATHOM_SIMD_FMA), so the lanes give the scalar code's bits where it does
// not, and agree with them to a few ulp where it does (the files are
// compiled with -ffp-contract=off: nothing else is fused).
//
// Highway's per-target header pattern: included once per target by
// foreach_target, after <hwy/highway.h>.
#if defined(FATHOM_INTEGRATE_EXP_NEG_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef FATHOM_INTEGRATE_EXP_NEG_INL_H_
#undef FATHOM_INTEGRATE_EXP_NEG_INL_H_
#else
#define FATHOM_INTEGRATE_EXP_NEG_INL_H_
#endif

#include <hwy/highway.h>

#include <cstddef>

#include "integrate/exp_neg.h"

HWY_BEFORE_NAMESPACE();
namespace fathom::simd {
namespace HWY_NAMESPACE {
namespace exp_v {
namespace hn = hwy::HWY_NAMESPACE;

using D = hn::ScalableTag<double>;
using V = hn::Vec<D>;
using M = hn::Mask<D>;
using DI = hn::RebindToSigned<D>;
using VI = hn::Vec<DI>;

#ifndef FATHOM_SIMD_FMA
#define FATHOM_SIMD_FMA 1
#endif

/// True where Fma fuses: the lanes' arithmetic then differs from the scalar
/// code's by a few ulp (simd::fused_lanes()).
constexpr bool kFused = FATHOM_SIMD_FMA != 0 && HWY_NATIVE_FMA != 0;

/// a·b + c: one rounding where kFused, else the product rounded, then the sum
/// (the scalar code's a * b + c).
HWY_INLINE V Fma(V a, V b, V c) {
    if constexpr (kFused) return hn::MulAdd(a, b, c);
    return hn::Add(hn::Mul(a, b), c);
}
/// c − a·b, likewise.
HWY_INLINE V NegFma(V a, V b, V c) {
    if constexpr (kFused) return hn::NegMulAdd(a, b, c);
    return hn::Sub(c, hn::Mul(a, b));
}

/// piece_position (fathom/transfer_function.h) per lane: a transfer
/// function's position (v − k0)·inv on its piece, in [0, 1].
HWY_INLINE V PiecePosition(V v, V k0, V inv) {
    return hn::Mul(hn::Sub(v, k0), inv);
}

/// c plus the number of keys k … k + n − 1 below v (kStrict) or at most v,
/// per lane, as int64 lanes: a masked increment per key.
template <bool kStrict>
HWY_INLINE VI AddCounts(D d, VI c, const double* keys, std::size_t n, V v) {
    const DI di;
    const VI one = hn::Set(di, 1);
    for (std::size_t k = 0; k < n; ++k) {
        const M m = kStrict ? hn::Lt(hn::Set(d, keys[k]), v) : hn::Le(hn::Set(d, keys[k]), v);
        c = hn::IfThenElse(hn::RebindMask(di, m), hn::Add(c, one), c);
    }
    return c;
}

/// The number of the first N of `keys` below v (kStrict) or at most v, per
/// lane: unrolled.
template <bool kStrict, std::size_t N>
HWY_INLINE VI CountKeysN(D d, const double* keys, V v) {
    return AddCounts<kStrict>(d, hn::Zero(DI()), keys, N, v);
}

/// The number of the n `keys` below v (kStrict) or at most v, per lane:
/// unrolled where n ≤ kMost (an instantiation per count), the keys past
/// kMost a loop.
template <bool kStrict, std::size_t kMost = 8>
HWY_INLINE VI CountKeys(D d, const double* keys, std::size_t n, V v) {
    if constexpr (kMost == 0) {
        return AddCounts<kStrict>(d, hn::Zero(DI()), keys, n, v);
    } else {
        if (n >= kMost)
            return AddCounts<kStrict>(d, CountKeysN<kStrict, kMost>(d, keys, v), keys + kMost, n - kMost, v);
        return CountKeys<kStrict, kMost - 1>(d, keys, n, v);
    }
}

/// taylor_estrin(r, from) per lane.
HWY_INLINE V Taylor(D d, V r, std::size_t from) {
    using preint::exp_detail::kTaylor;
    auto pair = [&](std::size_t i) {
        return Fma(hn::Set(d, kTaylor[from + i + 1]), r, hn::Set(d, kTaylor[from + i]));
    };
    const V r2 = hn::Mul(r, r), r4 = hn::Mul(r2, r2), r8 = hn::Mul(r4, r4);
    const V b0 = Fma(pair(2), r2, pair(0)), b1 = Fma(pair(6), r2, pair(4));
    const V b2 = Fma(pair(10), r2, pair(8)), b3 = pair(12);
    return Fma(Fma(b3, r4, b2), r8, Fma(b1, r4, b0));
}

/// exp_detail::reduce per lane (−x = k·ln 2 + r), and 2^k; valid where
/// −x lies in the reduction's range (InRange).
struct Reduced {
    V k, r, scale;
    Reduced(D d, V x) {
        using namespace preint::exp_detail;
        const DI di;
        const V y = hn::Neg(x);
        // (fused, k may differ from the scalar code's where y/ln 2 lies within
        // an ulp of a half-integer: r then stays within ln 2 / 2 and a hair)
        const V rounded = Fma(y, hn::Set(d, kInvLn2), hn::Set(d, kRound));
        k = hn::Sub(rounded, hn::Set(d, kRound));
        r = NegFma(k, hn::Set(d, kLn2Lo), NegFma(k, hn::Set(d, kLn2Hi), y));  // k·ln2_hi is exact
        // k from the rounded sum's low bits: 1.5·2^52 + k
        const VI ki = hn::Sub(hn::BitCast(di, rounded), hn::BitCast(di, hn::Set(d, kRound)));
        scale = hn::BitCast(d, hn::ShiftLeft<52>(hn::Add(ki, hn::Set(di, 1023))));
    }
};

HWY_INLINE M InRange(D d, V x) {
    using namespace preint::exp_detail;
    const V y = hn::Neg(x);
    return hn::And(hn::Le(hn::Set(d, kMinArg), y), hn::Le(y, hn::Set(d, kMaxArg)));
}

/// exp_neg(x) per lane, where InRange(x).
HWY_INLINE V ExpNeg(D d, V x) {
    const Reduced e(d, x);
    return hn::Mul(Taylor(d, e.r, 0), e.scale);
}

/// Below ln 2 / 2 with a margin: x·(1/ln 2) rounds to k = 0.
constexpr double kNoReduction = 0.34;

/// exp_neg(x) per lane where |x| < kNoReduction, so that k = 0 and r = −x:
/// the same bits without the reduction.
HWY_INLINE V ExpNegSmall(D d, V x) {
    return Taylor(d, hn::Neg(x), 0);
}

/// exp_neg(x) per lane where `used` (the others' values not used), without
/// the reduction where every such lane lies below kNoReduction (thin
/// pieces): the same bits either way.
HWY_INLINE V ExpNegOf(D d, V x, M used) {
    return hn::AllFalse(d, hn::AndNot(hn::Lt(x, hn::Set(d, kNoReduction)), used)) ? ExpNegSmall(d, x)
                                                                                  : ExpNeg(d, x);
}

/// exp_neg_thin(x) per lane (0 ≤ x ≤ 1/4).
HWY_INLINE V ExpNegThin(D d, V x) {
    using preint::exp_detail::kTaylor;
    const V r = hn::Neg(x);
    auto pair = [&](std::size_t i) { return Fma(hn::Set(d, kTaylor[i + 1]), r, hn::Set(d, kTaylor[i])); };
    const V r2 = hn::Mul(r, r), r4 = hn::Mul(r2, r2);
    return Fma(Fma(pair(6), r2, pair(4)), r4, Fma(pair(2), r2, pair(0)));
}

/// one_minus_exp_neg(x) per lane, where InRange(x).
HWY_INLINE V OneMinusExpNeg(D d, V x) {
    const Reduced e(d, x);
    const V m = hn::Mul(e.r, Taylor(d, e.r, 1));  // e^r − 1
    return NegFma(e.scale, m, hn::Sub(hn::Set(d, 1.0), e.scale));
}

}  // namespace exp_v
// NOLINTNEXTLINE(google-readability-namespace-comments)
}  // namespace HWY_NAMESPACE
}  // namespace fathom::simd
HWY_AFTER_NAMESPACE();

#endif  // per-target include guard
