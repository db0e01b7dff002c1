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

    /// Component `comp` at the eight corners of a located cell, x fastest:
    /// (0,0,0), (1,0,0), (0,1,0), (1,1,0), (0,0,1), … (as doubles).
    void corners(const GridCell& c, int comp, double* out) const {
        const std::int64_t sx = comps, sy = comps * nx, sz = comps * nx * ny;
        const T* q = data + c.base * comps + comp;
        const std::int64_t at[8] = {0, sx, sy, sy + sx, sz, sz + sx, sz + sy, sz + sy + sx};
        for (int i = 0; i < 8; ++i) out[i] = static_cast<double>(q[at[i]]);
    }

    /// The trilinear interpolant of corners q (as corners() orders them) at
    /// the fractions of cell c.
    [[nodiscard]] static double interpolate(const double* q, const GridCell& c) {
        const double c00 = q[0] + c.fx * (q[1] - q[0]);
        const double c10 = q[2] + c.fx * (q[3] - q[2]);
        const double c01 = q[4] + c.fx * (q[5] - q[4]);
        const double c11 = q[6] + c.fx * (q[7] - q[6]);
        const double c0 = c00 + c.fy * (c10 - c00);
        const double c1 = c01 + c.fy * (c11 - c01);
        return c0 + c.fz * (c1 - c0);
    }

    /// Component `comp` of the trilinear interpolant inside a located cell.
    [[nodiscard]] double interpolate(const GridCell& c, int comp = 0) const {
        double q[8];
        corners(c, comp, q);
        return interpolate(q, c);
    }

    [[nodiscard]] double operator()(const Vec3& p, int comp = 0) const { return interpolate(cell(p), comp); }
};

}  // namespace fathom
