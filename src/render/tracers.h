// The ray integrals instantiated per medium × model × integrator (included
// by the tracers_*.cpp translation units only).
#pragma once

#include "integrate/alpha.h"
#include "integrate/isosurface.h"
#include "integrate/preintegrated.h"
#include "integrate/projection.h"
#include "integrate/reference.h"
#include "integrate/riemann.h"
#include "render/medium.h"
#include "render/renderer_impl.h"
#include "render/shading.h"

namespace fathom {
namespace detail {

/// The medium as one ray sees it: shaded media learn the ray's direction.
template <class Medium>
decltype(auto) for_ray(const Medium& med, const RaySpan& sp) {
    if constexpr (Medium::kShaded) {
        Medium m = med;
        m.set_ray(sp);
        return m;
    } else {
        return (med);
    }
}

template <Model M, class Medium>
Tracer integrator_tracer(const Medium& med, const Renderer::Impl& im) {
    const RenderSettings& s = im.s;
    const double h = im.h;
    const Rgb bg = im.bg;
    const EmptySpace* es = im.skipper();
    const Accel acc{es, im.simd_source()};
    switch (s.integrator) {
        case IntegratorKind::riemann:
            return [med, s, h, bg, acc](const RaySpan& sp) {
                return integrate_riemann<M>(for_ray(med, sp), sp, s, h, bg, acc);
            };
        case IntegratorKind::alpha:
            return [med, s, h, bg, acc](const RaySpan& sp) {
                return integrate_alpha<M>(for_ray(med, sp), sp, s, h, bg, acc);
            };
        case IntegratorKind::reference: {
            const std::vector<double>* breaks = &im.tf.breakpoints();
            return [med, s, bg, breaks](const RaySpan& sp) {
                return ReferenceIntegrator<M, Medium>(for_ray(med, sp), sp, s.reference_tolerance, breaks)
                    .run(bg);
            };
        }
        case IntegratorKind::preintegrated:
        case IntegratorKind::preintegrated_simple: {
            const bool full = s.integrator == IntegratorKind::preintegrated;
            return [med, s, h, bg, full, acc](const RaySpan& sp) {
                return integrate_preintegrated<M>(for_ray(med, sp), sp, s, h, bg, full, acc.es, acc.simd);
            };
        }
    }
    throw Error("integrator", "unknown integrator");
}

// Projection modes over the scalar at the n + 1 segment ends (projection.h).
template <Model M, class T>
Tracer projection_tracer(const ScalarMedium<T>& med, const Renderer::Impl& im) {
    const double h = im.h;
    const simd::BatchSource* simd = im.simd_source();
    const MacrocellRanges* ranges = im.ranger();
    const EmptySpace* zeros = M == Model::average ? im.skipper() : nullptr;
    const double empty_value = im.empty_value;
    const MacrocellRanges* coarse =
        ranges != nullptr && im.coarse_ranges.dims()[0] > 0 ? &im.coarse_ranges : nullptr;
    return [med, h, simd, ranges, zeros, empty_value, coarse](const RaySpan& sp) {
        return project<M>(med, sp, h, simd, ranges, zeros, empty_value, coarse);
    };
}

template <class Medium>
Tracer make_tracer(const Medium& med, const Renderer::Impl& im) {
    switch (im.s.model) {
        case Model::emission_absorption:
            return integrator_tracer<Model::emission_absorption>(med, im);
        case Model::absorption:
            return integrator_tracer<Model::absorption>(med, im);
        case Model::emission:
            return integrator_tracer<Model::emission>(med, im);
        case Model::mip:
            if constexpr (Medium::kHasScalar) return projection_tracer<Model::mip>(med, im);
            break;
        case Model::minip:
            if constexpr (Medium::kHasScalar) return projection_tracer<Model::minip>(med, im);
            break;
        case Model::average:
            if constexpr (Medium::kHasScalar) return projection_tracer<Model::average>(med, im);
            break;
        case Model::isosurface:
            if constexpr (Medium::kHasScalar) {
                const RenderSettings& s = im.s;
                const double h = im.h;
                const Rgb bg = im.bg;
                const ShadeSetup* shade = &im.shade;
                const simd::BatchSource* simd = im.simd_source();
                const MacrocellRanges* ranges = im.ranger();
                const EmptySpace* es = im.skipper();
                return [med, s, h, bg, shade, simd, ranges, es](const RaySpan& sp) {
                    return trace_isosurfaces(med, sp, s, h, bg, *shade, simd, ranges, es);
                };
            }
            break;
    }
    throw Error("model '" + std::string(to_string(im.s.model)) + "'",
                "needs a scalar volume with a transfer function (pre-classified grids are refused)");
}

}  // namespace detail

template <class T>
Tracer scalar_tracer(const Volume& volume, const Renderer::Impl& im, bool gradient_work) {
    ScalarMedium<T> med{GridSampler<T>(volume), &im.tf};
    if (gradient_work) {  // the optical models only
        ShadedScalarMedium<T> sm{med};
        sm.setup = &im.shade;
        if (im.shade.gradients != nullptr) sm.grads = GridSampler<float>(*im.shade.gradients);
        switch (im.s.model) {
            case Model::absorption:
                return detail::integrator_tracer<Model::absorption>(sm, im);
            case Model::emission:
                return detail::integrator_tracer<Model::emission>(sm, im);
            default:
                return detail::integrator_tracer<Model::emission_absorption>(sm, im);
        }
    }
    return detail::make_tracer(med, im);
}

template <class D, class C>
Tracer grid_tracer(const Volume& density, const Volume& color, const Renderer::Impl& im) {
    GridMedium<D, C> med{GridSampler<D>(density), GridSampler<C>(color)};
    return detail::make_tracer(med, im);
}

}  // namespace fathom
