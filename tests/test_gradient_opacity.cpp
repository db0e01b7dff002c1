// Gradient opacity (TransferFunction::gradient_opacity_points: σ and g
// scaled by f(|∇v|)) and the precomputed gradient volume
// (GradientSource::precomputed): closed forms on linear fields, world units
// under anisotropic spacing, exact skipping, and the memory fallback.
#include <cmath>
#include <cstring>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/log.h"
#include "fathom/render.h"
#include "fathom/transfer_function.h"

#include "render/shading.h"
#include "simd_check.h"
#include "synthetic.h"

using namespace fathom;
using fathom::test::extinction_tf;
using fathom::test::make_volume;

namespace {

constexpr double kSigma = 0.05;
const Rgb kColor{0.9, 0.6, 0.3};

// v = 6·j with spacing (1, 2, 1): |∇v| = 3 per world unit everywhere (6 per
// voxel along j: a renderer that forgot the spacing would see 6).
const Volume& ramp() {
    static const Volume v = [] {
        Volume r = make_volume(21, 21, 21, [](double, double y, double) { return 6.0 * y; });
        r.set_spacing({1.0, 2.0, 1.0});
        return r;
    }();
    return v;
}

// f(m) = 1 − m/10 on [0, 10]: f(3) = 0.7, f(6) = 0.4.
TransferFunction ramp_tf() {
    TransferFunction tf = extinction_tf({{0.0, kSigma}}, kColor);
    tf.gradient_opacity_points = {{0.0, 1.0}, {10.0, 0.0}};
    return tf;
}

// Along +x through the middle (j = 10, y = 20 world): 20 world units of medium.
const Ray kRay{{-5.0, 20.0, 10.0}, {1.0, 0.0, 0.0}};

RenderSettings settings(IntegratorKind k) {
    RenderSettings s;
    s.integrator = k;
    s.termination = 0.0;
    s.step = 0.37;
    s.background = Rgb{0.2, 0.3, 0.4};
    return s;
}

// A sphere of radius 7 with a smooth edge: gradients of every direction and size.
const Volume& sphere() {
    static const Volume v = make_volume(24, 24, 24, [](double x, double y, double z) {
        const double r =
            std::sqrt((x - 11.5) * (x - 11.5) + (y - 11.5) * (y - 11.5) + (z - 11.5) * (z - 11.5));
        return 100.0 / (1.0 + std::exp(r - 7.0));
    });
    return v;
}

std::vector<float> pixels(const Volume& v, const TransferFunction& tf, const RenderSettings& s) {
    Renderer r(v, tf, s);
    const Bounds b = volume_bounds(v);
    const Image img = r.render(Camera::orbit(30.0, 20.0, 2.5, b.center, b.radius));
    return img.rgba;
}

}  // namespace

TEST(GradientOpacity, ScalesExtinctionByTheFactorOfTheWorldGradientMagnitude) {
    // σ' = 0.7·σ: I = I_bg·e^{−σ'L} + c·(1 − e^{−σ'L}) with L = 20.
    const double t = std::exp(-0.7 * kSigma * 20.0);
    for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated, IntegratorKind::reference})
        for (auto g : {GradientSource::on_the_fly, GradientSource::precomputed}) {
            RenderSettings s = settings(k);
            s.gradient = g;
            const RayResult r = Renderer(ramp(), ramp_tf(), s).trace(kRay);
            const double tol = k == IntegratorKind::reference ? 1e-5 : 1e-6;
            const Rgb bg = *s.background;
            for (int c = 0; c < 3; ++c)
                EXPECT_NEAR(r.radiance[c], bg[c] * t + kColor[c] * (1.0 - t), tol) << to_string(k);
            EXPECT_NEAR(r.alpha, 1.0 - t, tol) << to_string(k);
        }
}

TEST(GradientOpacity, WithoutSelfAttenuationTheSegmentScalesExactly) {
    // preintegrated-simple: each segment's E and τ scale by f = 0.7, so the
    // image equals the same integrator with σ scaled by 0.7.
    RenderSettings s = settings(IntegratorKind::preintegrated_simple);
    const RayResult mod = Renderer(ramp(), ramp_tf(), s).trace(kRay);
    const RayResult ref = Renderer(ramp(), extinction_tf({{0.0, 0.7 * kSigma}}, kColor), s).trace(kRay);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(mod.radiance[c], ref.radiance[c], 1e-12);
    EXPECT_NEAR(mod.alpha, ref.alpha, 1e-12);
}

TEST(GradientOpacity, AppliesToAbsorptionAndEmissionModels) {
    const double t = std::exp(-0.7 * kSigma * 20.0);
    RenderSettings s = settings(IntegratorKind::alpha);
    s.model = Model::absorption;
    const RayResult a = Renderer(ramp(), ramp_tf(), s).trace(kRay);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(a.radiance[c], (*s.background)[c] * t, 1e-9);
    s.model = Model::emission;  // I = I_bg + ∫ g = I_bg + c·σ'·L
    const RayResult e = Renderer(ramp(), ramp_tf(), s).trace(kRay);
    for (int c = 0; c < 3; ++c)
        EXPECT_NEAR(e.radiance[c], (*s.background)[c] + kColor[c] * 0.7 * kSigma * 20.0, 1e-9);
}

TEST(GradientOpacity, WorksWithShadingAndLeavesMipAlone) {
    RenderSettings s = settings(IntegratorKind::alpha);
    s.shading.enabled = true;
    s.shading.ambient = 0.0;
    s.shading.diffuse = 1.0;
    s.shading.specular = 0.0;
    // The gradient is along y, the head light along x: the diffuse term is 0,
    // opacity stays σ' = 0.7σ.
    const RayResult r = Renderer(ramp(), ramp_tf(), s).trace(kRay);
    EXPECT_NEAR(r.alpha, 1.0 - std::exp(-0.7 * kSigma * 20.0), 1e-6);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.radiance[c], (*s.background)[c] * (1.0 - r.alpha), 1e-6);
    // MIP shows c(max v) whatever the gradient.
    s.model = Model::mip;
    s.shading.enabled = false;
    const RayResult m = Renderer(ramp(), ramp_tf(), s).trace(kRay);
    EXPECT_EQ(m.radiance, kColor);
}

TEST(GradientOpacity, SkippingStaysBitIdentical) {
    // σ is 0 below v = 20 and f is 0 for steep edges: skipping must still
    // leave every pixel unchanged; and the scalar path (no zero split
    // either) gives them too, to the SIMD lanes' few ulp where they fuse
    // multiply–adds (simd_check.h).
    TransferFunction tf = extinction_tf({{0.0, 0.0}, {20.0, 0.0}, {60.0, 0.3}}, kColor);
    tf.gradient_opacity_points = {{0.0, 1.0}, {20.0, 0.5}, {30.0, 0.0}};
    for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated,
                   IntegratorKind::preintegrated_simple}) {
        RenderSettings s = settings(k);
        s.width = s.height = 24;
        s.skip_empty = true;
        const auto on = pixels(sphere(), tf, s);
        s.skip_empty = false;
        const auto all = pixels(sphere(), tf, s);
        ASSERT_EQ(on.size(), all.size());
        EXPECT_EQ(std::memcmp(on.data(), all.data(), on.size() * sizeof(float)), 0) << to_string(k);
        s.simd = false;
        const auto off = pixels(sphere(), tf, s);
        EXPECT_TRUE(test::pixels_agree(on, off)) << to_string(k);
        // And the modulation does change the picture.
        TransferFunction plain = tf;
        plain.gradient_opacity_points.clear();
        EXPECT_NE(pixels(sphere(), plain, s), off) << to_string(k);
    }
}

TEST(GradientOpacity, JsonRoundTripAndErrors) {
    const std::string text = R"({"format": "fathom-tf/1", "color": [[0, 1, 1, 1]], "opacity": [[0, 0.5]],
                                 "gradient_opacity": [[0, 0], [5, 1]]})";
    const TransferFunction tf = TransferFunction::from_json_text(text, "t.json");
    ASSERT_EQ(tf.gradient_opacity_points.size(), 2u);
    EXPECT_EQ(tf.gradient_opacity_points[1], (std::pair<double, double>{5.0, 1.0}));
    const TransferFunction back = TransferFunction::from_json_text(tf.to_json(), "u.json");
    EXPECT_EQ(back.gradient_opacity_points, tf.gradient_opacity_points);
    const Classifier cl(tf, 1.0);
    EXPECT_TRUE(cl.has_gradient_opacity());
    EXPECT_DOUBLE_EQ(cl.gradient_factor(2.5), 0.5);
    EXPECT_DOUBLE_EQ(cl.gradient_factor(100.0), 1.0);
    for (const char* bad : {R"([[0, 1.5]])", R"([[-1, 0.5]])", R"([[2, 0.5], [1, 0.5]])", R"([])"}) {
        const std::string t = std::string(R"({"format": "fathom-tf/1", "color": [[0, 1, 1, 1]], )") +
                              R"("opacity": [[0, 0.5]], "gradient_opacity": )" + bad + "}";
        try {
            (void)TransferFunction::from_json_text(t, "bad.json");
            ADD_FAILURE() << "accepted " << bad;
        } catch (const Error& e) {
            EXPECT_NE(std::string(e.what()).find("bad.json"), std::string::npos);
            EXPECT_NE(std::string(e.what()).find("gradient_opacity"), std::string::npos) << e.what();
        }
    }
}

TEST(PrecomputedGradients, NodeGradientsOfALinearFieldAreExactUnderARotatedLattice) {
    // v = 2i − 3j + 0.5k on a rotated, anisotropic lattice: ∇v = Wᵀ·(2, −3, 0.5).
    Volume v = make_volume(9, 8, 7, [](double x, double y, double z) { return 2 * x - 3 * y + 0.5 * z; });
    const double a = 0.4;
    v.set_axes(Mat3::from_columns({1.5 * std::cos(a), 1.5 * std::sin(a), 0}, {-std::sin(a), std::cos(a), 0},
                                  {0, 0, 0.7}));
    const Mat3 w2i = v.axes().inverse();
    const Volume g = node_gradients(v, w2i, 2);
    ASSERT_EQ(g.components(), 3);
    Vec3 expect;
    const double du[3] = {2, -3, 0.5};
    for (int i = 0; i < 3; ++i) expect[i] = w2i.m[0][i] * du[0] + w2i.m[1][i] * du[1] + w2i.m[2][i] * du[2];
    for (std::int64_t k = 0; k < 7; k += 3)
        for (std::int64_t j = 0; j < 8; j += 7)  // border rows use one-sided differences
            for (std::int64_t i = 0; i < 9; ++i)
                for (int c = 0; c < 3; ++c) EXPECT_NEAR(g.value(i, j, k, c), expect[c], 1e-5);
}

TEST(PrecomputedGradients, ShadedImagesAgreeWithOnTheFly) {
    TransferFunction tf = extinction_tf({{0.0, 0.0}, {40.0, 0.0}, {60.0, 0.4}}, kColor);
    RenderSettings s = settings(IntegratorKind::alpha);
    s.width = s.height = 32;
    s.shading.enabled = true;
    const auto fly = pixels(sphere(), tf, s);
    s.gradient = GradientSource::precomputed;
    const auto pre = pixels(sphere(), tf, s);
    ASSERT_EQ(fly.size(), pre.size());
    // Interpolated node differences vs differences of the interpolant: the
    // same normals up to the curvature of a 7-voxel sphere.
    double sum = 0, worst = 0;
    bool differ = false;
    for (std::size_t i = 0; i < fly.size(); ++i) {
        const double d = std::abs(static_cast<double>(fly[i]) - pre[i]);
        sum += d;
        worst = std::max(worst, d);
        differ = differ || d > 0;
    }
    EXPECT_TRUE(differ) << "the precomputed path was not taken";
    EXPECT_LT(sum / static_cast<double>(fly.size()), 5e-3);
    EXPECT_LT(worst, 0.08);
}

TEST(PrecomputedGradients, TooLargeFallsBackToOnTheFlyWithAWarning) {
    TransferFunction tf = extinction_tf({{0.0, 0.0}, {40.0, 0.0}, {60.0, 0.4}}, kColor);
    RenderSettings s = settings(IntegratorKind::preintegrated);
    s.width = s.height = 16;
    s.shading.enabled = true;
    const auto fly = pixels(sphere(), tf, s);
    s.gradient = GradientSource::precomputed;
    s.gradient_memory = 1000;
    std::vector<std::string> warnings;
    const WarningSink old = set_warning_sink([&](const std::string& w) { warnings.push_back(w); });
    const auto pre = pixels(sphere(), tf, s);
    set_warning_sink(old);
    ASSERT_EQ(warnings.size(), 1u);
    EXPECT_NE(warnings[0].find("on the fly"), std::string::npos) << warnings[0];
    EXPECT_EQ(fly, pre);
}
