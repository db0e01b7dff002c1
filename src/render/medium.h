// Media: what a ray sees at a point (ARCHITECTURE.md "Medium"). Both kinds
// are cheap value types evaluated in index space:
//   ScalarMedium<T>  a scalar volume classified by a transfer function;
//   GridMedium<D, C> pre-classified density σ and RGB color grids, g = σ·c.
#pragma once

#include "fathom/math.h"
#include "fathom/transfer_function.h"

#include "integrate/accumulator.h"
#include "volume/sampler.h"

namespace fathom {

template <class T>
struct ScalarMedium {
    static constexpr bool kHasScalar = true;
    static constexpr bool kShaded = false;
    GridSampler<T> grid;
    const Classifier* tf = nullptr;

    [[nodiscard]] double scalar(const Vec3& p) const { return grid(p); }
    /// σ(v) and g(v), evaluating σ once (g = σ·c, or q when associated).
    [[nodiscard]] MediumSample classify(double v) const {
        MediumSample m{tf->sigma(v), tf->color(v)};
        if (!tf->associated())
            for (double& c : m.source) c *= m.sigma;
        return m;
    }
    [[nodiscard]] MediumSample at(const Vec3& p) const { return classify(scalar(p)); }
    /// What pre-integration needs at a segment end: the scalar.
    [[nodiscard]] double end_sample(const Vec3& p) const { return scalar(p); }
};

/// σ and the non-associated color at a point of pre-classified grids.
struct GridEndSample {
    double sigma = 0;
    Rgb color{};
};

template <class D, class C>
struct GridMedium {
    static constexpr bool kHasScalar = false;
    static constexpr bool kShaded = false;
    GridSampler<D> density;
    GridSampler<C> color;

    [[nodiscard]] MediumSample at(const Vec3& p) const {
        const auto cell = density.cell(p);  // both grids share the lattice
        const double s = density.interpolate(cell);
        return {
            s,
            {s * color.interpolate(cell, 0), s * color.interpolate(cell, 1), s * color.interpolate(cell, 2)}};
    }
    [[nodiscard]] GridEndSample end_sample(const Vec3& p) const {
        const auto cell = density.cell(p);
        return {density.interpolate(cell),
                {color.interpolate(cell, 0), color.interpolate(cell, 1), color.interpolate(cell, 2)}};
    }
};

}  // namespace fathom
