// Local illumination (docs/shading.md): the gradient of the trilinear field
// by central differences, correct for anisotropic spacing and rotated
// lattices (chain rule through the world-to-index matrix), and Blinn–Phong
// factors that shade the source term g, not the opacity.
#pragma once

#include <cmath>
#include <vector>

#include "fathom/math.h"
#include "fathom/render.h"

#include "integrate/accumulator.h"
#include "integrate/ray_span.h"
#include "render/medium.h"

namespace fathom {

/// Per-sample work on the gradient ∇v: Blinn–Phong lighting and/or the
/// transfer function's gradient opacity.
struct ShadeSetup {
    double ka = 0, kd = 0, ks = 0, p = 1;
    std::vector<Light> lights;  // unit directions; empty: a head light
    Mat3 world_to_index, index_to_world;
    bool light = true;                     // false: gradient opacity only
    const Classifier* modulate = nullptr;  // gradient opacity f(|∇v|), or nullptr
    const Volume* gradients = nullptr;     // precomputed node gradients (3 × float32), or nullptr
};

/// g' = (g·diffuse + σ·specular)·opacity and σ' = σ·opacity, per channel;
/// opacity is the gradient-opacity factor (1 without one).
struct ShadeFactors {
    Rgb diffuse{1, 1, 1}, specular{0, 0, 0};
    double opacity = 1;
};

/// The unit vector toward the eye of a ray whose index-space direction is dp.
inline Vec3 view_toward_eye(const Mat3& index_to_world, const Vec3& dp) {
    const Vec3 d = index_to_world * dp;
    return d * (-1.0 / length(d));
}

/// Half the step of the central differences, in voxels.
inline constexpr double kGradientStep = 0.5;

/// ∇f in world units at index-space point p: central differences of the
/// trilinear interpolant along each lattice axis (clamped at the border),
/// then ∂f/∂x_i = Σ_j W_ji ∂f/∂u_j with W the world-to-index matrix.
template <class T>
Vec3 world_gradient(const GridSampler<T>& g, const Vec3& p, const Mat3& w2i) {
    constexpr double h = kGradientStep;
    const double du[3] = {(g({p.x + h, p.y, p.z}) - g({p.x - h, p.y, p.z})) / (2 * h),
                          (g({p.x, p.y + h, p.z}) - g({p.x, p.y - h, p.z})) / (2 * h),
                          (g({p.x, p.y, p.z + h}) - g({p.x, p.y, p.z - h})) / (2 * h)};
    Vec3 r;
    for (int i = 0; i < 3; ++i) {
        double s = 0;
        for (int j = 0; j < 3; ++j) s += w2i.m[j][i] * du[j];
        r[i] = s;
    }
    return r;
}

/// The highlight's x^p: by repeated squaring where the shininess p is a
/// whole number from 1 to 128 (VTK's and ParaView's usual powers; within
/// about 2p ulp of std::pow, and the multiplications a SIMD lane repeats),
/// std::pow otherwise.
inline bool whole_shininess(double p) {
    return p >= 1.0 && p <= 128.0 && p == std::floor(p);
}
inline double highlight_pow(double x, double p) {
    if (!whole_shininess(p)) return std::pow(x, p);
    auto n = static_cast<unsigned>(p);
    double r = 1.0, b = x;
    for (;;) {
        if ((n & 1u) != 0) r *= b;
        n >>= 1;
        if (n == 0) return r;
        b *= b;
    }
}

/// Blinn–Phong with two-sided lighting; `view` is the unit vector from the
/// sample toward the eye. Where the gradient vanishes there is no normal:
/// the sample is lit as if it faced every light, without highlight.
inline ShadeFactors shade_factors(const ShadeSetup& s, const Vec3& grad, const Vec3& view) {
    ShadeFactors f{{s.ka, s.ka, s.ka}, {0, 0, 0}};
    const double len = length(grad);
    const Vec3 n = len > 0 ? grad * (1.0 / len) : Vec3{};
    auto light = [&](const Vec3& l, const Rgb& color) {
        if (!(len > 0)) {
            for (int c = 0; c < 3; ++c) f.diffuse[c] += s.kd * color[c];
            return;
        }
        const double ndl = std::abs(dot(n, l));
        Vec3 hv = l + view;
        const double hl = length(hv);
        const double ndh = hl > 0 ? std::abs(dot(n, hv)) / hl : 0.0;
        const double spec = s.ks > 0 ? s.ks * highlight_pow(ndh, s.p) : 0.0;
        for (int c = 0; c < 3; ++c) {
            f.diffuse[c] += s.kd * ndl * color[c];
            f.specular[c] += spec * color[c];
        }
    };
    if (s.lights.empty()) {
        light(view, {1, 1, 1});
    } else {
        for (const Light& l : s.lights) light(l.direction, l.color);
    }
    return f;
}

/// The factors of a sample whose gradient is g under `view`: lighting
/// (where s.light) and gradient opacity (where s.modulate).
inline ShadeFactors factors_of(const ShadeSetup& s, const Vec3& g, const Vec3& view) {
    ShadeFactors f = s.light ? shade_factors(s, g, view) : ShadeFactors{};
    if (s.modulate != nullptr) f.opacity = s.modulate->gradient_factor(length(g));
    return f;
}

/// A pre-integrated segment shaded with the factors at its midpoint, taken
/// as constant over the segment (Lum, Wilson and Ma 2004): g' = g·D + σ·S
/// integrates to D·E + S·∫σ·e^{−τ} = D·E + S·(1 − t), or D·E + S·τ
/// without self-attenuation (`full` false).
///
/// Gradient opacity scales σ and g by f, constant over the segment:
/// without self-attenuation exactly E' = f·E, t' = t^f; with it,
/// t' = t^f and E' = E·(1 − t^f)/(1 − t) (opacity-weighted, exact where
/// the TF is constant over the segment).
inline Segment shade_segment(Segment seg, const ShadeFactors& sf, bool full) {
    double t = seg.transmittance;
    if (sf.opacity != 1.0) {
        const double tf = std::pow(t, sf.opacity);
        const double scale = !full ? sf.opacity : (t < 1.0 ? (1.0 - tf) / (1.0 - t) : sf.opacity);
        for (double& r : seg.radiance) r *= scale;
        seg.transmittance = t = tf;
    }
    const double a = full ? 1.0 - t : (t > 0.0 ? -std::log(t) : 0.0);
    for (int c = 0; c < 3; ++c) seg.radiance[c] = seg.radiance[c] * sf.diffuse[c] + a * sf.specular[c];
    return seg;
}

/// Node gradients in world units (3 float32 components per node): central
/// differences of the nodes along each lattice axis (one-sided at the
/// border), then the chain rule through the world-to-index matrix, as
/// world_gradient does for the trilinear field. Built with `threads` threads.
Volume node_gradients(const Volume& v, const Mat3& world_to_index, int threads);

/// A scalar volume classified by a transfer function, with per-sample
/// gradient work: lighting (the ray's direction is set per ray by set_ray
/// for the head light and highlights) and/or gradient opacity.
template <class T>
struct ShadedScalarMedium : ScalarMedium<T> {
    static constexpr bool kShaded = true;
    const ShadeSetup* setup = nullptr;
    GridSampler<float> grads{};  // setup->gradients, when there is one
    Vec3 view{0, 0, 1};

    void set_ray(const RaySpan& sp) { view = view_toward_eye(setup->index_to_world, sp.dp); }
    [[nodiscard]] Vec3 gradient(const Vec3& p) const {
        if (setup->gradients != nullptr) {
            const auto cell = grads.cell(p);
            return {grads.interpolate(cell, 0), grads.interpolate(cell, 1), grads.interpolate(cell, 2)};
        }
        return world_gradient(this->grid, p, setup->world_to_index);
    }
    [[nodiscard]] ShadeFactors factors(const Vec3& p) const { return factors_of(*setup, gradient(p), view); }
    void shade(const Vec3& p, MediumSample& m) const {
        const ShadeFactors f = factors(p);
        for (int c = 0; c < 3; ++c)
            m.source[c] = (m.source[c] * f.diffuse[c] + m.sigma * f.specular[c]) * f.opacity;
        m.sigma *= f.opacity;
    }
    [[nodiscard]] MediumSample at(const Vec3& p) const {
        MediumSample m = ScalarMedium<T>::at(p);
        shade(p, m);
        return m;
    }
};

}  // namespace fathom
