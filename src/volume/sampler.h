// Trilinear sampling of a node-centred grid in index space (eq. (20)).
// A small value type over a typed view of a Volume; no allocation, no virtual
// calls. Positions are clamped to the box [0, n−1] (rays sample inside it up
// to rounding).
#pragma once

#include <algorithm>
#include <cstdint>

#include "fathom/math.h"
#include "fathom/volume.h"

namespace fathom {

/// A located cell: the linear node index of its (i0, j0, k0) corner and the
/// fractional position inside it. Independent of the sample type, so grids on
/// one lattice share it.
struct GridCell {
    std::int64_t base;
    double fx, fy, fz;
};

template <class T>
struct GridSampler {
    const T* data = nullptr;
    std::int64_t nx = 0, ny = 0, nz = 0;
    int comps = 1;

    GridSampler() = default;
    explicit GridSampler(const Volume& v)
        : data(v.data<T>()), nx(v.dims()[0]), ny(v.dims()[1]), nz(v.dims()[2]), comps(v.components()) {}

    static void locate(double p, std::int64_t n, std::int64_t& i, double& f) {
        const double x = std::clamp(p, 0.0, static_cast<double>(n - 1));
        i = std::min(static_cast<std::int64_t>(x), n - 2);
        f = x - static_cast<double>(i);
    }

    [[nodiscard]] GridCell cell(const Vec3& p) const {
        std::int64_t i, j, k;
        GridCell c{};
        locate(p.x, nx, i, c.fx);
        locate(p.y, ny, j, c.fy);
        locate(p.z, nz, k, c.fz);
        c.base = i + nx * (j + ny * k);
        return c;
    }

    /// Component `comp` of the trilinear interpolant inside a located cell.
    [[nodiscard]] double interpolate(const GridCell& c, int comp = 0) const {
        const std::int64_t sx = comps, sy = comps * nx, sz = comps * nx * ny;
        const T* q = data + c.base * comps + comp;
        const double c00 = q[0] + c.fx * (static_cast<double>(q[sx]) - q[0]);
        const double c10 = q[sy] + c.fx * (static_cast<double>(q[sy + sx]) - q[sy]);
        const double c01 = q[sz] + c.fx * (static_cast<double>(q[sz + sx]) - q[sz]);
        const double c11 = q[sz + sy] + c.fx * (static_cast<double>(q[sz + sy + sx]) - q[sz + sy]);
        const double c0 = c00 + c.fy * (c10 - c00);
        const double c1 = c01 + c.fy * (c11 - c01);
        return c0 + c.fz * (c1 - c0);
    }

    [[nodiscard]] double operator()(const Vec3& p, int comp = 0) const { return interpolate(cell(p), comp); }
};

}  // namespace fathom
