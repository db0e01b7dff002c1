// The isosurface model: the ray is sampled on the uniform segment grid of
// eq. (8); wherever the scalar crosses an iso-value between two samples the
// crossing is refined by bisection to 1e−5 voxel, shaded with the gradient
// there (Blinn–Phong, render/shading.h) and composited front to back with
// the surface's opacity. Crossings closer than one step apart are found as
// long as they are of different iso-values; one iso-value crossed twice
// within a step is missed (a thin shell thinner than the step).
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <vector>

#include "fathom/render.h"

#include "integrate/projection.h"
#include "integrate/ray_span.h"
#include "integrate/simd_classify.h"
#include "render/empty_space.h"
#include "render/medium.h"
#include "render/shading.h"

namespace fathom {

/// The interval of scalars [lo, hi] on the same side of every iso-value as
/// v (x < iso exactly where v < iso), for skipping: samples in it cross
/// none between them or with v.
inline std::array<double, 2> iso_interval(const std::vector<IsoSurface>& isos, double v) {
    double lo = -INFINITY, hi = INFINITY;
    for (const IsoSurface& iso : isos) {
        if (v < iso.value) hi = std::min(hi, std::nextafter(iso.value, -INFINITY));
        if (!(v < iso.value)) lo = std::max(lo, iso.value);
    }
    return {lo, hi};
}

/// Where the scalar f(t) crosses `iso` between t = lo and t = hi (f(lo) <
/// iso exactly where `below`; f(hi) on the other side): bisection until the
/// bracket is at most `tol` long or its midpoint no longer splits it; the
/// last bracket's midpoint.
template <class F>
double bisect_crossing(F&& f, double lo, double hi, double tol, double iso, bool below) {
    while (hi - lo > tol) {
        const double mid = 0.5 * (lo + hi);
        if (mid <= lo || mid >= hi) break;
        ((f(mid) < iso) == below ? lo : hi) = mid;
    }
    return 0.5 * (lo + hi);
}

/// The scalar along the ray sp (GridSampler's bits) for bisect_crossing:
/// its points lie within a cell or two, so the corners of the last cell
/// are kept and a point in it takes only the interpolation.
template <class T>
class CellCache {
public:
    CellCache(const GridSampler<T>& g, const RaySpan& sp) : g_(g), sp_(sp) {}
    double operator()(double t) {
        const GridCell c = g_.cell(sp_.at(t));
        if (c.base != base_) {
            base_ = c.base;
            g_.corners(c, 0, q_);
        }
        return GridSampler<T>::interpolate(q_, c);
    }

private:
    const GridSampler<T>& g_;
    const RaySpan& sp_;
    std::int64_t base_ = -1;
    double q_[8] = {};
};

/// The isosurfaces along one ray. The ends 1 .. n − 1 are interpolated
/// kBatch at a time (scalar_ends: GridSampler's bits), the last at t_far.
///
/// With `es` (EmptySpace::for_isosurfaces), the ray walks its runs of ends
/// (RunFinder, the pixel bounds included): a run in "empty" macrocells,
/// where every end lies on the same sides of the iso-values, takes its
/// first end only (its pair with the end before is tested; the ends after
/// it cross nothing, and the next pair's test needs only their side, which
/// is the first's); the other runs are evaluated. This needs each step to
/// reach a touching macrocell at most (|dp_a|·δ ≤ a macrocell edge less a
/// cell on every axis); otherwise, or without `es`, with macrocell ranges, a batch of
/// ends whose macrocells all lie on the same sides as the end before it
/// is skipped.
template <class V>
RayResult trace_isosurfaces(const ScalarMedium<V>& med, const RaySpan& sp, const RenderSettings& s, double h,
                            const Rgb& bg, const ShadeSetup& shade, const simd::BatchSource* simd = nullptr,
                            const MacrocellRanges* ranges = nullptr, const EmptySpace* es = nullptr) {
    const std::int64_t n = segment_count(sp.length(), h);
    const double delta = sp.length() / static_cast<double>(n);
    const auto& isos = s.isosurfaces;
    auto f = [&](double t) { return med.scalar(sp.at(t)); };
    // Bisection stops when the bracket is below 1e−5 voxel along every axis.
    const double speed = std::max({std::abs(sp.dp.x), std::abs(sp.dp.y), std::abs(sp.dp.z)});
    const double tol = 1e-5 / speed;
    const Vec3 d = shade.index_to_world * sp.dp;
    const Vec3 view = d * (-1.0 / length(d));

    struct Hit {
        double t;
        std::size_t k;
    };
    RayResult r;
    double T = 1.0, weighted = 0.0;  // Σ T·a·t for the expected depth
    double ta = sp.t_near, fa = f(ta);
    // The scalars on the same side of every iso-value as fa.
    std::array<double, 2> side = iso_interval(isos, fa);
    // The segment from (ta, fa) to the end at tb: true once the ray stops.
    auto segment = [&](double tb, double fb) {
        if (fb >= side[0] && fb <= side[1]) {  // no iso-value crossed
            ta = tb;
            fa = fb;
            return false;
        }
        std::array<Hit, 16> hits{};
        std::size_t nh = 0;
        for (std::size_t k = 0; k < isos.size() && k < hits.size(); ++k) {
            const double iso = isos[k].value;
            if ((fa < iso) == (fb < iso)) continue;
            const bool below = fa < iso;
            hits[nh++] = {bisect_crossing(CellCache<V>(med.grid, sp), ta, tb, tol, iso, below), k};
        }
        std::sort(hits.begin(), hits.begin() + static_cast<std::ptrdiff_t>(nh),
                  [](const Hit& a, const Hit& b) { return a.t < b.t; });
        for (std::size_t i = 0; i < nh; ++i) {
            const IsoSurface& iso = isos[hits[i].k];
            const Vec3 p = sp.at(hits[i].t);
            const ShadeFactors sf =
                shade_factors(shade, world_gradient(med.grid, p, shade.world_to_index), view);
            for (int c = 0; c < 3; ++c)
                r.radiance[c] += T * iso.opacity * (iso.color[c] * sf.diffuse[c] + sf.specular[c]);
            weighted += T * iso.opacity * hits[i].t;
            T *= 1.0 - iso.opacity;
            r.first_hit = std::min(r.first_hit, hits[i].t);
            if (T < s.termination) {
                r.alpha = 1.0 - T;
                r.depth = weighted / r.alpha;
                return true;
            }
        }
        ta = tb;
        fa = fb;
        side = iso_interval(isos, fa);
        return false;
    };
    alignas(64) double ends[simd::kBatch];
    const SampleGrid grid{&sp, delta, 0.0, 0};  // end j at t_near + j·δ
    auto t_of = [&](std::int64_t j) { return grid.t(j); };
    // Ends j0 .. j1 evaluated in batches: true once the ray stops.
    auto evaluate = [&](std::int64_t j0, std::int64_t j1) {
        for (; j0 <= j1; j0 += simd::kBatch) {
            const int count = static_cast<int>(std::min<std::int64_t>(simd::kBatch, j1 - j0 + 1));
            scalar_ends(med, sp, delta, simd, j0, count, ends);
            for (int l = 0; l < count; ++l)
                if (segment(t_of(j0 + l), ends[l])) return true;
        }
        return false;
    };
    // consecutive ends in touching macrocells
    const double step = es != nullptr ? es->touching_step() : 0.0;
    if (es != nullptr && std::abs(sp.dp.x * delta) <= step && std::abs(sp.dp.y * delta) <= step &&
        std::abs(sp.dp.z * delta) <= step) {
        const RunFinder runs(*es, grid);
        for (std::int64_t j = 1; j < n;) {
            const RunFinder::Run run = runs.run_through(j, +1, n - 1);
            if (run.empty) {
                if (segment(t_of(j), f(t_of(j)))) return r;
                if (run.last > j) ta = t_of(run.last);  // fa keeps its side, which is every skipped end's
            } else if (evaluate(j, run.last)) {
                return r;
            }
            j = run.last + 1;
        }
    } else {
        for (std::int64_t j0 = 1; j0 < n; j0 += simd::kBatch) {
            const std::int64_t j1 = std::min(j0 + simd::kBatch - 1, n - 1);
            if (ranges != nullptr && ranges->within(grid.at(j0), grid.at(j1), side[0], side[1])) {
                ta = t_of(j1);  // fa keeps its side, which is every skipped end's
                continue;
            }
            if (evaluate(j0, j1)) return r;
        }
    }
    if (segment(sp.t_far, f(sp.t_far))) return r;
    for (int c = 0; c < 3; ++c) r.radiance[c] += T * bg[c];
    r.alpha = 1.0 - T;
    if (r.alpha > 0.0) r.depth = weighted / r.alpha;
    return r;
}

}  // namespace fathom
