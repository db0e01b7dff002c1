// Checks shared by the SIMD tests: a batch of interpolated samples against
// GridSampler, on every target this CPU runs, and the agreement of the SIMD
// path's numbers and images with the scalar path's.
//
// Where the active target's kernels fuse multiply–adds (simd::fused_lanes():
// FATHOM_SIMD_FMA, AVX2 and up) each of those roundings differs from the
// scalar code's by up to half an ulp, so the lanes agree with the scalar
// code to a few ulp of double, within the tolerance each check states; on
// other targets (SSE4) and in builds with FATHOM_SIMD_FMA off they give its
// bits, and the checks ask for them.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fathom/image.h"
#include "fathom/volume.h"

#include "integrate/simd_classify.h"
#include "volume/sampler.h"

namespace fathom::test {

/// A SIMD lane's `got` against the scalar code's `want`: the same bits, or,
/// where the active target's lanes fuse, within `tol` (NaN as NaN).
inline bool lanes_agree(double got, double want, double tol) {
    if (std::bit_cast<std::uint64_t>(got) == std::bit_cast<std::uint64_t>(want)) return true;
    if (!simd::fused_lanes()) return false;
    if (std::isnan(got) || std::isnan(want)) return false;
    return std::abs(got - want) <= tol;
}

/// A fused lane's trilinear value against GridSampler's: the seven lerps
/// of three levels, each rounding a product–sum once instead of twice, move
/// it by a few ulp of the largest corner's magnitude; 16 ulp of the largest
/// node's magnitude `m`.
inline double lerp_tolerance(double m) {
    return 0x1p-49 * m;
}

/// The largest |node| of v (lerp_tolerance's m).
inline double largest_magnitude(const Volume& v) {
    const auto [lo, hi] = v.value_range();
    return std::max(std::abs(lo), std::abs(hi));
}

/// How far a value of an image of the SIMD path may lie from the scalar
/// path's where the lanes fuse, relative to max(1, |value|): their few ulp of
/// double move a pixel, rounded to float, by an ulp of float (6e−8) at
/// most, unless a ray's transmittance passes the termination threshold
/// within them.
inline constexpr double kImageTolerance = 1e-6;

/// Pixel values of the SIMD path (rendered with the active target) against
/// the scalar path's: bit for bit, or, where the lanes fuse, within
/// kImageTolerance.
inline bool pixels_agree(const std::vector<float>& x, const std::vector<float>& y) {
    if (x.size() != y.size()) return false;
    for (std::size_t i = 0; i < x.size(); ++i) {
        const double p = x[i], q = y[i];
        if (!lanes_agree(p, q, kImageTolerance * std::max(1.0, std::abs(q)))) return false;
    }
    return true;
}

/// pixels_agree for RGBA and the depth outputs.
inline bool images_agree(const Image& a, const Image& b) {
    return pixels_agree(a.rgba, b.rgba) && pixels_agree(a.depth, b.depth) &&
           pixels_agree(a.first_hit, b.first_hit);
}

/// Interpolates 3·kBatch − 3 samples of ray g from src in one call (more
/// than one batch, the last partial) on every target and compares each
/// with GridSampler over v (the same lattice, x-fastest; lanes_agree within
/// lerp_tolerance of v's largest |node|, `magnitude`), and the bits of
/// those below src.zero_below with the values (of a partial batch too).
/// Returns how many samples were compared, or −1 after a failure naming
/// the target, `what` and the sample.
inline int batch_matches_sampler(const simd::BatchSource& src, const simd::RayGrid& g, const Volume& v,
                                 double magnitude, const std::string& what) {
    int compared = 0;
    constexpr int kCount = 3 * simd::kBatch - 3;
    alignas(64) double got[3 * simd::kBatch], part[simd::kBatch];
    for (auto t : simd::available_targets()) {
        simd::force_target(t);
        std::uint64_t below = ~std::uint64_t{0}, part_below = ~std::uint64_t{0};
        simd::interpolate_batch(src, g, 0, kCount, got, &below);
        constexpr int kPart = simd::kBatch - 5;
        simd::interpolate_batch(src, g, 0, kPart, part, &part_below);
        if ((below >> kCount) != 0) {
            ADD_FAILURE() << simd::active_target() << " " << what << ": below bits past the last sample";
            simd::force_target(0);
            return -1;
        }
        for (int l = 0; l < kCount; ++l)
            if (((below >> l) & 1u) != static_cast<std::uint64_t>(got[l] < src.zero_below)) {
                ADD_FAILURE() << simd::active_target() << " " << what << " sample " << l << ": below bit "
                              << ((below >> l) & 1u) << " for " << got[l] << " and " << src.zero_below;
                simd::force_target(0);
                return -1;
            }
        if (part_below != (below & ((std::uint64_t{1} << kPart) - 1u))) {
            ADD_FAILURE() << simd::active_target() << " " << what << ": below bits of " << kPart
                          << " samples " << part_below << " against " << below;
            simd::force_target(0);
            return -1;
        }
        for (int l = 0; l < kCount; ++l) {
            const Vec3 p = g.p0 + g.dp * (g.t_near + (l + g.offset) * g.delta);
            const double want = visit_dtype(v.dtype(), [&]<class T>(T*) { return GridSampler<T>(v)(p); });
            if (!lanes_agree(got[l], want, lerp_tolerance(magnitude))) {
                ADD_FAILURE() << simd::active_target() << " " << what << " sample " << l << ": " << got[l]
                              << " against " << want;
                simd::force_target(0);
                return -1;
            }
            ++compared;
        }
    }
    simd::force_target(0);
    return compared;
}

}  // namespace fathom::test
