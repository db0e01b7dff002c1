// Pre-integrated classification (docs/theory.md eqs. (15)–(18)).
#include <cmath>
#include <random>

#include <gtest/gtest.h>

#include "fathom/preintegration.h"
#include "fathom/render.h"

#include "integrate/preintegrated.h"
#include "synthetic.h"

using namespace fathom;
using fathom::test::make_volume;

namespace {

// A TF with a jump, a narrow spike and a smooth color ramp.
TransferFunction spiky_tf() {
    TransferFunction tf;
    tf.alpha_kind = TransferFunction::Alpha::extinction;
    tf.alpha_points = {{0.0, 0.0}, {0.3, 0.2},  {0.45, 0.4}, {0.45, 2.5},
                       {0.5, 0.3}, {0.51, 6.0}, {0.52, 0.3}, {1.0, 0.8}};
    tf.color_points = {
        {0.0, {1.0, 0.1, 0.0}}, {0.5, {0.2, 1.0, 0.3}}, {0.5, {0.9, 0.9, 0.9}}, {1.0, {0.0, 0.3, 1.0}}};
    return tf;
}

// eq. (16) by brute force: midpoint rule in l with the running depth.
Segment brute_force(const Classifier& c, double vf, double vb, double delta, bool full) {
    const int m = 200000;
    double depth = 0;
    Rgb E{0, 0, 0};
    for (int i = 0; i < m; ++i) {
        const double l = (i + 0.5) / m;
        const double v = vf + l * (vb - vf);
        const double s = c.sigma(v);
        const Rgb g = c.source(v);
        const double w = delta / m * (full ? std::exp(-(depth + 0.5 * s * delta / m)) : 1.0);
        for (int k = 0; k < 3; ++k) E[k] += w * g[k];
        depth += s * delta / m;
    }
    return {std::exp(-depth), E};
}

}  // namespace

TEST(Preintegrated, SegmentIntegralsMatchBruteForce) {
    TransferFunction emissive = spiky_tf();  // associated emission: g = q (eq. (16) with q)
    emissive.associated = true;
    for (const auto& tf : {spiky_tf(), emissive}) {
        const Classifier c(tf, 1.0);
        std::mt19937 rng(7);
        std::uniform_real_distribution<double> v(-0.1, 1.1), d(0.05, 4.0);
        std::vector<std::array<double, 2>> pairs = {{0.2, 0.8},   {0.8, 0.2},   {0.4, 0.4},
                                                    {0.44, 0.46}, {0.46, 0.44}, {0.505, 0.515},
                                                    {0.45, 0.45}, {0.0, 1.0},   {1.0, 0.0}};
        for (int i = 0; i < 12; ++i) pairs.push_back({v(rng), v(rng)});
        for (const auto& [vf, vb] : pairs) {
            const double delta = d(rng);
            for (bool full : {true, false}) {
                const Segment got = preintegrate_scalar<Model::emission_absorption>(c, vf, vb, delta, full);
                const Segment want = brute_force(c, vf, vb, delta, full);
                // the brute force's own error at jumps is ~ jump·δ/m ≈ 5e−6
                EXPECT_NEAR(got.transmittance, want.transmittance, 1e-5) << vf << " " << vb << " " << delta;
                for (int k = 0; k < 3; ++k)
                    EXPECT_NEAR(got.radiance[k], want.radiance[k], 1e-5 * std::max(1.0, want.radiance[k]))
                        << vf << " " << vb << " " << delta << (full ? " full" : " simple");
            }
        }
    }
}

TEST(Preintegrated, ConstantSegmentEqualsAlphaQuadrature) {
    const Volume vol = make_volume(6, 6, 6, [](double, double, double) { return 0.37; });
    const TransferFunction tf = spiky_tf();
    RenderSettings a;
    a.integrator = IntegratorKind::alpha;
    a.termination = 0;
    a.step = 0.7;
    RenderSettings p = a;
    p.integrator = IntegratorKind::preintegrated;
    const Ray ray{{-1.0, 2.5, 2.2}, normalize(Vec3{1.0, 0.1, 0.05})};
    const RayResult ra = Renderer(vol, tf, a).trace(ray), rp = Renderer(vol, tf, p).trace(ray);
    for (int k = 0; k < 3; ++k) EXPECT_DOUBLE_EQ(rp.radiance[k], ra.radiance[k]);
    EXPECT_DOUBLE_EQ(rp.alpha, ra.alpha);
}

TEST(Preintegrated, SpikeAtOneVoxelBeatsAlphaAtAnEighth) {
    const Volume vol = make_volume(20, 20, 20, [](double x, double y, double z) {
        return 0.5 + 0.45 * std::sin(0.35 * x + 0.15 * y) * std::cos(0.3 * z + 0.2 * y);
    });
    const TransferFunction tf = spiky_tf();
    const Bounds b = volume_bounds(vol);
    const Camera cam = Camera::orbit(30, 25, 2.5, b.center, b.radius);
    auto render = [&](IntegratorKind k, double step) {
        RenderSettings s;
        s.width = s.height = 24;
        s.integrator = k;
        s.step = step;
        s.termination = 0;
        return Renderer(vol, tf, s).render(cam);
    };
    const Image ref = render(IntegratorKind::reference, 1.0);
    auto rmse = [&](const Image& img) {
        double e = 0;
        for (std::size_t i = 0; i < img.rgba.size(); ++i)
            if (i % 4 != 3) e += std::pow(static_cast<double>(img.rgba[i]) - ref.rgba[i], 2);
        return std::sqrt(e / static_cast<double>(img.rgba.size() / 4 * 3));
    };
    const double pre = rmse(render(IntegratorKind::preintegrated, 1.0));
    const double alpha = rmse(render(IntegratorKind::alpha, 0.125));
    EXPECT_LT(pre, alpha) << "preintegrated at 1 voxel " << pre << ", alpha at 1/8 voxel " << alpha;
}

TEST(Preintegrated, PreclassifiedGridsAreLinearAlongTheSegment) {
    // density ramps linearly along x: σ(t) = a + b·t; color constant →
    // absorption exact, radiance c(1 − T) exact (particle model, constant c).
    const Volume density = make_volume(9, 3, 3, [](double x, double, double) { return 0.05 + 0.04 * x; });
    Volume color({9, 3, 3}, DType::f64, 3);
    for (std::int64_t k = 0; k < 3; ++k)
        for (std::int64_t j = 0; j < 3; ++j)
            for (std::int64_t i = 0; i < 9; ++i) color.set_value(i, j, k, 0.5, 1);
    RenderSettings s;
    s.termination = 0;
    s.step = 0.9;
    const RayResult r = Renderer(density, color, s).trace({{-2.0, 1.0, 1.0}, {1.0, 0.0, 0.0}});
    const double a = double(0.05f), b = (double(0.05f + 0.04f * 8) - a) / 8;  // float32 grid values
    const double T = std::exp(-(a * 8 + b * 32));
    EXPECT_NEAR(r.alpha, 1 - T, 1e-6);
    EXPECT_NEAR(r.radiance[1], 0.5 * (1 - T), 1e-6);
    EXPECT_EQ(r.radiance[0], 0.0);
}

TEST(Preintegrated, FastTableBuildEqualsDirectEvaluation) {
    const Classifier c(spiky_tf(), 1.0);
    for (bool full : {true, false})
        for (double delta : {0.3, 2.0}) {
            // knots fall between grid nodes: range −0.07..1.13 over 41 nodes
            const auto fast = build_preintegration_table(c, -0.07, 1.13, 41, delta, full, 2);
            const auto direct = build_preintegration_table_direct(c, -0.07, 1.13, 41, delta, full);
            for (std::size_t k = 0; k < fast.alpha.size(); ++k) {
                ASSERT_NEAR(fast.alpha[k], direct.alpha[k], 2e-6) << k;
                for (int ch = 0; ch < 3; ++ch)
                    ASSERT_NEAR(fast.color[k * 3 + ch], direct.color[k * 3 + ch], 2e-6)
                        << k << (full ? " full" : " simple");
            }
        }
}
