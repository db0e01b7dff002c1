// The SIMD kernels' gathers (simd_classify.cpp, simd_preint.cpp): the
// values Highway's GatherOffset and GatherIndex return, lane for lane. On
// the AVX2 target, whose vectors of doubles hold 4 lanes, they are four
// scalar loads put together in a register instead of the gather
// instruction: AMD's cores (Zen 1 to 4) and Intel's before Skylake run
// AVX2 gathers as long microcoded sequences, slower than the loads
// (docs/performance.md, "Gathers"). The other targets keep Highway's own:
// SSE4 has no gather instruction (Highway loads lane by lane already), and
// the AVX-512 ones keep the instruction: 8 loads and their inserts measured
// even on a Zen 5 and slower on a Zen 4.
//
// Highway's per-target header pattern: included once per target by
// foreach_target, after <hwy/highway.h>.
#if defined(FATHOM_INTEGRATE_GATHER_INL_H_) == defined(HWY_TARGET_TOGGLE)
#ifdef FATHOM_INTEGRATE_GATHER_INL_H_
#undef FATHOM_INTEGRATE_GATHER_INL_H_
#else
#define FATHOM_INTEGRATE_GATHER_INL_H_
#endif

#include <hwy/highway.h>

#include <cstdint>
#include <cstring>

HWY_BEFORE_NAMESPACE();
namespace fathom::simd {
namespace HWY_NAMESPACE {
namespace gather {
namespace hn = hwy::HWY_NAMESPACE;

/// The 32- or 64-bit words at byte offsets `o` from `base` (GatherOffset).
template <class DW, class W, class VO>
HWY_INLINE hn::Vec<DW> Words(DW dw, const W* base, VO o) {
#if HWY_TARGET == HWY_AVX2
    using T = hn::TFromD<DW>;
    if constexpr (hn::MaxLanes(DW()) == 4 && (sizeof(T) == 4 || sizeof(T) == 8)) {
        HWY_ALIGN hn::TFromV<VO> at[4];
        hn::Store(o, hn::RebindToSigned<DW>(), at);
        const auto* bytes = reinterpret_cast<const unsigned char*>(base);
        T w[4];
        for (int i = 0; i < 4; ++i) std::memcpy(&w[i], bytes + at[i], sizeof(T));
        if constexpr (sizeof(T) == 4)
            return hn::Vec<DW>{_mm_setr_epi32(static_cast<int>(w[0]), static_cast<int>(w[1]),
                                              static_cast<int>(w[2]), static_cast<int>(w[3]))};
        else
            return hn::Vec<DW>{_mm256_setr_epi64x(static_cast<long long>(w[0]), static_cast<long long>(w[1]),
                                                  static_cast<long long>(w[2]),
                                                  static_cast<long long>(w[3]))};
    }
#endif
    return hn::GatherOffset(dw, base, o);
}

/// base[i] per lane (GatherIndex) of doubles.
template <class D, class VI>
HWY_INLINE hn::Vec<D> Doubles(D d, const double* base, VI i) {
#if HWY_TARGET == HWY_AVX2
    if constexpr (hn::MaxLanes(D()) == 4) {
        HWY_ALIGN hn::TFromV<VI> at[4];
        hn::Store(i, hn::RebindToSigned<D>(), at);
        return hn::Vec<D>{_mm256_setr_pd(base[at[0]], base[at[1]], base[at[2]], base[at[3]])};
    }
#endif
    return hn::GatherIndex(d, base, i);
}

}  // namespace gather
// NOLINTNEXTLINE(google-readability-namespace-comments)
}  // namespace HWY_NAMESPACE
}  // namespace fathom::simd
HWY_AFTER_NAMESPACE();

#endif  // per-target include guard
