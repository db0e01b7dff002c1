// node_gradients: the precomputed gradient volume (GradientSource::precomputed).
#include <algorithm>

#include "core/parallel.h"
#include "render/shading.h"

namespace fathom {

Volume node_gradients(const Volume& v, const Mat3& world_to_index, int threads) {
    const std::int64_t nx = v.dims()[0], ny = v.dims()[1], nz = v.dims()[2];  // (lambdas capture them)
    Volume g(v.dims(), DType::f32, 3);
    float* out = g.data<float>();
    auto slabs = [&](std::int64_t k0, std::int64_t k1) {
        visit_dtype(v.dtype(), [&]<class T>(T*) {
            const T* d = v.data<T>();
            auto at = [&](std::int64_t i, std::int64_t j, std::int64_t k) {
                return static_cast<double>(d[i + nx * (j + ny * k)]);
            };
            // Central difference along one axis (one-sided at the border), per voxel.
            auto diff = [](double lo, double hi, std::int64_t n_lo, std::int64_t n_hi) {
                return (hi - lo) / static_cast<double>(n_hi - n_lo);
            };
            for (std::int64_t k = k0; k < k1; ++k)
                for (std::int64_t j = 0; j < ny; ++j)
                    for (std::int64_t i = 0; i < nx; ++i) {
                        const std::int64_t i0 = std::max<std::int64_t>(i - 1, 0),
                                           i1 = std::min(i + 1, nx - 1);
                        const std::int64_t j0 = std::max<std::int64_t>(j - 1, 0),
                                           j1 = std::min(j + 1, ny - 1);
                        const std::int64_t k0_ = std::max<std::int64_t>(k - 1, 0),
                                           k1_ = std::min(k + 1, nz - 1);
                        const double du[3] = {diff(at(i0, j, k), at(i1, j, k), i0, i1),
                                              diff(at(i, j0, k), at(i, j1, k), j0, j1),
                                              diff(at(i, j, k0_), at(i, j, k1_), k0_, k1_)};
                        float* o = out + 3 * (i + nx * (j + ny * k));
                        for (int a = 0; a < 3; ++a) {
                            double s = 0;
                            for (int b = 0; b < 3; ++b) s += world_to_index.m[b][a] * du[b];
                            o[a] = static_cast<float>(s);
                        }
                    }
        });
    };
    parallel_chunks(nz, threads, slabs);
    return g;
}

}  // namespace fathom
