// Pre-integrated classification (docs/theory.md eqs. (15)–(18)).
#include <algorithm>
#include <cmath>
#include <limits>
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

// Without self-attenuation a segment is a difference of the integral
// functions (eqs. (15), (17)) wherever the ramp is steep: it agrees with the
// sum over the ramp's pieces to rounding, scaled by how much of S and G the
// difference cancels, for every model, both colour kinds and values far
// outside the transfer function's range; flatter ramps take the pieces.
TEST(Preintegrated, IntegralFunctionsMatchTheRampPieces) {
    TransferFunction emissive = spiky_tf();
    emissive.associated = true;
    // CT units: breakpoints far from 0, values over thousands
    const TransferFunction ct = TransferFunction::preset("ct-bone", {-1024.0, 3071.0});
    long steep = 0, flat = 0;
    for (const auto& tf : {spiky_tf(), emissive, ct}) {
        const Classifier c(tf, 1.0);
        const IntegralFunctions& f = c.integrals();
        ASSERT_FALSE(f.empty());
        const double k0 = f.knots.front(), range = f.knots.back() - k0;
        double smax = 0, gmax = 0;
        for (double v : f.knots)
            for (double e : {-1e-9, 0.0, 1e-9}) {
                smax = std::max(smax, c.sigma(v + e * range));
                for (double g : c.source(v + e * range)) gmax = std::max(gmax, std::abs(g));
            }
        std::mt19937 rng(11);
        std::uniform_real_distribution<double> v(k0 - 0.5 * range, k0 + 1.5 * range), d(0.05, 4.0),
            u(0.0, 1.0);
        for (int i = 0; i < 4000; ++i) {
            const double vf = i % 9 == 0 ? f.knots[static_cast<std::size_t>(i) % f.knots.size()] : v(rng);
            const double scale = std::abs(vf - k0) + 1e-3 * range;
            // far apart, close (1e−6 of the range), just past the threshold, within it
            const double step = i % 4 == 0   ? v(rng) - vf
                                : i % 4 == 1 ? 1e-6 * range * (u(rng) - 0.5)
                                : i % 4 == 2 ? 2.0 * preint::kFlatRamp * scale * (1.0 + u(rng))
                                             : 0.4 * preint::kFlatRamp * scale * u(rng);
            const double vb = vf + step, delta = d(rng);
            const bool is_steep = preint::steep_ramp(f, vf, vb);
            (is_steep ? steep : flat) += 1;
            auto pieces = [&]<Model M>() {
                RampIntegral<M> acc(delta, false);
                for_each_ramp_piece(c, vf, vb, [&](const RampPiece& p) { acc.add(p); });
                return acc.result();
            };
            // the difference's rounding: a few ulp of S, G at the ends, over |v_b − v_f|
            const double cancel = 64 * std::numeric_limits<double>::epsilon() * delta *
                                  (std::abs(vf - k0) + std::abs(vb - k0) + range) /
                                  std::max(std::abs(vb - vf), 1e-300);
            auto check = [&]<Model M>() {
                const Segment got = preintegrate_scalar<M>(c, vf, vb, delta, false),
                              want = pieces.template operator()<M>();
                const double tol_t = std::min(1e-7 * delta * smax, cancel * smax) + 1e-15;
                EXPECT_NEAR(got.transmittance, want.transmittance, tol_t)
                    << vf << " → " << vb << " δ " << delta;
                for (int k = 0; k < 3; ++k)
                    EXPECT_NEAR(
                        got.radiance[k], want.radiance[k],
                        std::min(1e-7 * delta * gmax, cancel * gmax) + 1e-15 * std::abs(want.radiance[k]))
                        << vf << " → " << vb << " δ " << delta;
            };
            check.template operator()<Model::emission_absorption>();
            check.template operator()<Model::absorption>();
            check.template operator()<Model::emission>();
        }
    }
    EXPECT_GT(steep, 2 * flat);
    EXPECT_GT(flat, 1000);
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
