// SIMD pre-integration (docs/performance.md "SIMD"): the segments between
// a batch of segment ends, several at once, each lane performing exactly
// the operations of preintegrate_scalar (integrate/preintegrated.h) in the
// same order: the ramp cut at the transfer function's control values, each
// piece's closed forms and Gauss–Legendre sums with exp_neg, composed as
// RampIntegral; without self-attenuation, where the ramp is steep, the
// integral functions' differences (preint::integral_segment), S and G taken
// once per end. So the results are the scalar code's bits; tests check every
// target against it. Lanes the vector code does not take (a piece deeper
// than 40 that is not constant, a scalar that is not finite, an exponent
// beyond exp_neg's reduction) are flagged and left to the scalar code.
#pragma once

#include <cstdint>

#include "fathom/render.h"

#include "integrate/simd_classify.h"

namespace fathom::simd {

/// The segments between ends l and l + 1 of a batch, l = 0 … count − 2.
struct SegmentBatch {
    alignas(64) double transmittance[kBatch];
    alignas(64) double radiance[3][kBatch];
    /// Bit l set: segment l was not computed (the scalar code's).
    std::uint32_t scalar = 0;
};

/// Pre-integrates the segments between consecutive `ends` (the scalar at
/// segment ends j0 … j0 + count − 1, count ≤ kBatch + 1, camera side first;
/// `ends` holds kBatch + 8 values, those past the last read but not used)
/// of length `delta` under `model`
/// (emission–absorption, absorption or emission), with self-attenuation
/// when `full`. src.sigma, src.color, src.breaks, src.associated and
/// src.integrals describe the transfer function (without src.integrals every
/// segment takes the ramp's pieces), and src.zero_below the medium's zero
/// range for `model` (zero_below in render/empty_space.h; −∞ for none): the
/// ramps leave out their pieces below it. Segments with their bit set in
/// `skip` are not computed (flagged as scalar).
void preintegrate_batch(const BatchSource& src, Model model, bool full, double delta, const double* ends,
                        int count, std::uint32_t skip, SegmentBatch& out);

/// Segments from several windows or steps (and rays) packed into whole vectors:
/// segment i runs vf[i] → vb[i] over delta[i]. Arrays are padded to whole
/// vectors of the widest target (their values past `count` read, not used).
struct SegmentPack {
    static constexpr std::size_t kCapacity = 256;
    static constexpr std::size_t kPadded = kCapacity + 8;
    alignas(64) double vf[kPadded], vb[kPadded], delta[kPadded];
    alignas(64) double transmittance[kPadded], radiance[3][kPadded];
    alignas(64) double scalar[kPadded];  // 1: not computed (the scalar code's)
    int count = 0;
};

/// Pre-integrates pack's segments first … count − 1 (`first` a multiple of
/// 8, so that they start a vector on every target) as preintegrate_batch
/// does each segment (the same operations lane by lane, so the same bits).
void preintegrate_pack(const BatchSource& src, Model model, bool full, SegmentPack& pack, int first = 0);

}  // namespace fathom::simd
