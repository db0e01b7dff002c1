// Gradient shading (src/render/shading.h, docs/shading.md): Lambert's
// cosine law on planes, normals under anisotropic spacing, the specular
// term, lights from the scene, and what shading must not change.
#include <cmath>
#include <cstring>
#include <limits>
#include <numbers>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/render.h"

#include "render/shading.h"
#include "simd_check.h"
#include "synthetic.h"

using namespace fathom;
using fathom::test::extinction_tf;
using fathom::test::make_volume;

namespace {

constexpr double kSigma = 0.05;
const Rgb kColor{0.9, 0.6, 0.3};

// f = x (index units): planes of constant value, normal ±x everywhere.
const Volume& plane_field() {
    static const Volume v = make_volume(21, 21, 21, [](double x, double, double) { return x; });
    return v;
}

RenderSettings settings(IntegratorKind k) {
    RenderSettings s;
    s.integrator = k;
    s.termination = 0.0;
    s.step = 0.3;
    return s;
}

Shading lambert() {
    Shading sh;
    sh.enabled = true;
    sh.ambient = 0.0;
    sh.diffuse = 1.0;
    sh.specular = 0.0;
    return sh;
}

// A ray through the middle of the box at angle θ from +x in the x–y plane.
Ray ray_at(double theta) {
    const Vec3 d{std::cos(theta), std::sin(theta), 0.0};
    return {Vec3{10.0, 10.0, 10.3} - d * 30.0, d};
}

constexpr std::array<IntegratorKind, 5> kAll{IntegratorKind::alpha, IntegratorKind::riemann,
                                             IntegratorKind::preintegrated,
                                             IntegratorKind::preintegrated_simple, IntegratorKind::reference};

}  // namespace

TEST(Shading, APlaneUnderAHeadLightFollowsLambertsCosineLaw) {
    const TransferFunction tf = extinction_tf({{0.0, kSigma}}, kColor);
    for (auto k : kAll)
        for (double theta : {0.0, 0.3, 0.7, 1.1, std::numbers::pi / 2}) {
            RenderSettings s = settings(k);
            const RayResult plain = Renderer(plane_field(), tf, s).trace(ray_at(theta));
            s.shading = lambert();
            const RayResult lit = Renderer(plane_field(), tf, s).trace(ray_at(theta));
            const double tol = k == IntegratorKind::reference ? 1e-5 : 1e-12;
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(lit.radiance[c], std::abs(std::cos(theta)) * plain.radiance[c], tol)
                    << to_string(k) << " θ = " << theta;
            EXPECT_EQ(lit.alpha, plain.alpha) << "shading must not touch opacity";
        }
}

TEST(Shading, NormalsFollowTheWorldGradientUnderAnisotropicSpacing) {
    // f = u + v in index units with spacing (2, 1, 1): ∇f = (1/2, 1, 0) in
    // world units, so the normal is (1, 2, 0)/√5, not (1, 1, 0)/√2.
    Volume v = make_volume(21, 21, 21, [](double x, double y, double) { return x + y; });
    v.set_spacing({2.0, 1.0, 1.0});
    const TransferFunction tf = extinction_tf({{0.0, kSigma}}, kColor);
    const Vec3 center{20.0, 10.0, 10.0};
    auto trace = [&](const Vec3& dir, const Shading& sh) {
        RenderSettings s = settings(IntegratorKind::alpha);
        s.shading = sh;
        // central differences are one-sided within half a voxel of the border
        s.crop = WorldBox{{1.5, 1.0, 1.0}, {38.5, 19.0, 19.0}};
        const Vec3 d = dir * (1.0 / length(dir));
        return Renderer(v, tf, s).trace({center - d * 40.0, d});
    };
    const Shading off;
    Shading sh = lambert();
    for (const Vec3 dir : {Vec3{1, 2, 0}, Vec3{-1, -2, 0}})  // along the normal: cos = 1
        EXPECT_NEAR(trace(dir, sh).radiance[0], trace(dir, off).radiance[0], 1e-12);
    EXPECT_NEAR(trace({2, -1, 0}, sh).radiance[0], 0.0, 1e-12);  // perpendicular: cos = 0
    EXPECT_GT(trace({1, -1, 0}, sh).radiance[0], 0.01);          // the isotropic guess would give 0 here
    sh.ambient = 0.25;
    EXPECT_NEAR(trace({2, -1, 0}, sh).radiance[1], 0.25 * trace({2, -1, 0}, off).radiance[1], 1e-12);
}

TEST(Shading, SpecularHighlightIsWhiteAndWeightedByOpacity) {
    // k_s = 1, p = 1, head light: h = v, so S = |cos θ| and g' = σ·S.
    const TransferFunction tf = extinction_tf({{0.0, kSigma}}, kColor);
    for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated}) {
        RenderSettings s = settings(k);
        s.shading.enabled = true;
        s.shading.ambient = s.shading.diffuse = 0.0;
        s.shading.specular = 1.0;
        s.shading.shininess = 1.0;
        const double theta = 0.6;
        const RayResult r = Renderer(plane_field(), tf, s).trace(ray_at(theta));
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(r.radiance[c], std::cos(theta) * r.alpha, 1e-12) << to_string(k);
    }
}

TEST(Shading, HighlightPowersAreWithinAFewUlpOfPow) {
    // Whole shininess: repeated squaring, within 2p ulp of std::pow (relative);
    // otherwise std::pow itself.
    for (int p = 1; p <= 128; ++p)
        for (int i = 0; i <= 1000; ++i) {
            const double x = i / 1000.0 + (i % 7) * 1e-5;
            const double want = std::pow(x, p), got = highlight_pow(x, p);
            ASSERT_NEAR(got, want, 2.0 * p * std::numeric_limits<double>::epsilon() * want) << x << "^" << p;
        }
    EXPECT_TRUE(whole_shininess(10));
    EXPECT_FALSE(whole_shininess(0.0));
    EXPECT_FALSE(whole_shininess(10.5));
    EXPECT_FALSE(whole_shininess(129));
    EXPECT_EQ(highlight_pow(0.7, 10.5), std::pow(0.7, 10.5));
    EXPECT_EQ(highlight_pow(0.7, 0.0), 1.0);
    EXPECT_EQ(highlight_pow(0.0, 10.0), 0.0);
    EXPECT_EQ(highlight_pow(1.0, 128.0), 1.0);
}

TEST(Shading, DirectionalLightsFromTheSettings) {
    const TransferFunction tf = extinction_tf({{0.0, kSigma}}, kColor);
    RenderSettings s = settings(IntegratorKind::alpha);
    const RayResult plain = Renderer(plane_field(), tf, s).trace(ray_at(0.0));
    s.shading = lambert();
    s.shading.lights = {{{0, 3, 0}, {1, 1, 1}}};  // along the planes: n·l = 0
    EXPECT_NEAR(Renderer(plane_field(), tf, s).trace(ray_at(0.0)).radiance[0], 0.0, 1e-12);
    s.shading.lights = {{{-1, 0, 0}, {0.5, 1, 2}}, {{0, 1, 0}, {1, 1, 1}}};  // colored, along the normal
    const RayResult r = Renderer(plane_field(), tf, s).trace(ray_at(0.0));
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(r.radiance[c], s.shading.lights[0].color[c] * plain.radiance[c], 1e-12);
}

TEST(Shading, SkippingStaysExactAndGridsAreRefused) {
    const Volume v = make_volume(30, 26, 22, [](double x, double y, double z) {
        const double d = std::sqrt((x - 15) * (x - 15) + (y - 12) * (y - 12) + (z - 11) * (z - 11));
        return std::max(0.0, 1.0 - d / 8.0);
    });
    TransferFunction tf = extinction_tf({{0.0, 0.0}, {0.3, 0.0}, {0.6, 1.5}}, kColor);
    const Bounds b = volume_bounds(v);
    const Camera cam = Camera::orbit(30, 20, 2.5, b.center, b.radius);
    for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated}) {
        RenderSettings s = settings(k);
        s.width = s.height = 32;
        s.shading.enabled = true;
        const Image on = Renderer(v, tf, s).render(cam);
        s.skip_empty = false;
        const Image all = Renderer(v, tf, s).render(cam);
        EXPECT_EQ(std::memcmp(on.rgba.data(), all.rgba.data(), on.rgba.size() * sizeof(float)), 0)
            << to_string(k);
        s.simd = false;  // the scalar path: the SIMD lanes' few ulp where they fuse (simd_check.h)
        const Image off = Renderer(v, tf, s).render(cam);
        EXPECT_TRUE(test::images_agree(on, off)) << to_string(k);
        s.shading.enabled = false;
        const Image flat = Renderer(v, tf, s).render(cam);
        EXPECT_NE(std::memcmp(on.rgba.data(), flat.rgba.data(), on.rgba.size() * sizeof(float)), 0);
    }
    Volume color({30, 26, 22}, DType::f32, 3);
    Volume density({30, 26, 22}, DType::f32);
    RenderSettings s;
    s.shading.enabled = true;
    EXPECT_THROW(Renderer(density, color, s), Error);
    s.shading.lights = {{{0, 0, 0}, {1, 1, 1}}};
    EXPECT_THROW(s.validate(), Error);
    s.shading.lights.clear();
    s.shading.shininess = -1;
    EXPECT_THROW(s.validate(), Error);
}
