// A check shared by the SIMD tests: a batch of interpolated samples against
// GridSampler, on every target this CPU runs.
#pragma once

#include <string>

#include <gtest/gtest.h>

#include "fathom/volume.h"

#include "integrate/simd_classify.h"
#include "volume/sampler.h"

namespace fathom::test {

/// Interpolates the kBatch samples of ray g from src on every target and
/// compares each with GridSampler over v (the same lattice, x-fastest).
/// Returns how many samples were compared, or −1 after a failure naming the
/// target, `what` and the sample.
inline int batch_matches_sampler(const simd::BatchSource& src, const simd::RayGrid& g, const Volume& v,
                                 const std::string& what) {
    int compared = 0;
    alignas(64) double got[simd::kBatch];
    for (auto t : simd::available_targets()) {
        simd::force_target(t);
        simd::interpolate_batch(src, g, 0, simd::kBatch, got);
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
