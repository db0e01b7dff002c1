// A check shared by the SIMD tests: a batch of interpolated samples against
// GridSampler, on every target this CPU runs.
#pragma once

#include <cstdint>
#include <string>

#include <gtest/gtest.h>

#include "fathom/volume.h"

#include "integrate/simd_classify.h"
#include "volume/sampler.h"

namespace fathom::test {

/// Interpolates the kBatch samples of ray g from src on every target and
/// compares each with GridSampler over v (the same lattice, x-fastest), and
/// the bits of those below src.zero_below with the values (of a partial
/// batch too). Returns how many samples were compared, or −1 after a
/// failure naming the target, `what` and the sample.
inline int batch_matches_sampler(const simd::BatchSource& src, const simd::RayGrid& g, const Volume& v,
                                 const std::string& what) {
    int compared = 0;
    alignas(64) double got[simd::kBatch], part[simd::kBatch];
    for (auto t : simd::available_targets()) {
        simd::force_target(t);
        std::uint32_t below = ~0u, part_below = ~0u;
        simd::interpolate_batch(src, g, 0, simd::kBatch, got, &below);
        constexpr int kPart = simd::kBatch - 5;
        simd::interpolate_batch(src, g, 0, kPart, part, &part_below);
        for (int l = 0; l < simd::kBatch; ++l)
            if (((below >> l) & 1u) != static_cast<std::uint32_t>(got[l] < src.zero_below)) {
                ADD_FAILURE() << simd::active_target() << " " << what << " sample " << l << ": below bit "
                              << ((below >> l) & 1u) << " for " << got[l] << " and " << src.zero_below;
                simd::force_target(0);
                return -1;
            }
        if (part_below != (below & ((1u << kPart) - 1u))) {
            ADD_FAILURE() << simd::active_target() << " " << what << ": below bits of " << kPart
                          << " samples " << part_below << " against " << below;
            simd::force_target(0);
            return -1;
        }
        for (int l = 0; l < simd::kBatch; ++l) {
            const Vec3 p = g.p0 + g.dp * (g.t_near + (l + g.offset) * g.delta);
            const double want = visit_dtype(v.dtype(), [&]<class T>(T*) { return GridSampler<T>(v)(p); });
            if (got[l] != want) {
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
