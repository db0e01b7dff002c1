// The quadratures against analytic solutions, each other and the reference
// (docs/theory.md eqs. (6), (9)–(12), (21), (22), (24)).
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/render.h"

#include "synthetic.h"

using namespace fathom;
using fathom::test::extinction_tf;
using fathom::test::make_volume;

namespace {

RenderSettings settings(IntegratorKind k, SamplePoint sp = SamplePoint::near, double step = 0.5) {
    RenderSettings s;
    s.integrator = k;
    s.sample_point = sp;
    s.step = step;
    s.termination = 0.0;
    return s;
}

// A ray along +x through the middle of an n³ box: t_near = 1, L = n − 1.
Ray x_ray(double n) {
    return {{-1.0, (n - 1) / 2.0 + 0.25, (n - 1) / 2.0 - 0.125}, {1.0, 0.0, 0.0}};
}

constexpr std::array<IntegratorKind, 5> kAll{IntegratorKind::riemann, IntegratorKind::alpha,
                                             IntegratorKind::reference, IntegratorKind::preintegrated,
                                             IntegratorKind::preintegrated_simple};

}  // namespace

TEST(Integrators, HomogeneousMediumMatchesClosedForm) {
    // eq. (6): I = I_bg e^{−σL} + c (1 − e^{−σL})
    const Volume vol = make_volume(5, 5, 5, [](double, double, double) { return 1.0; });
    const double sigma = 0.7, L = 4.0;
    const Rgb c{0.9, 0.5, 0.2}, bg{0.1, 0.2, 0.3};
    const auto tf = extinction_tf({{0.0, sigma}}, c);
    for (auto kind : {IntegratorKind::alpha, IntegratorKind::reference, IntegratorKind::preintegrated}) {
        for (auto sp : {SamplePoint::near, SamplePoint::mid}) {
            auto s = settings(kind, sp, 0.3);
            s.background = bg;
            const RayResult r = Renderer(vol, tf, s).trace(x_ray(5));
            for (int ch = 0; ch < 3; ++ch)
                EXPECT_NEAR(r.radiance[ch],
                            bg[ch] * std::exp(-sigma * L) + c[ch] * (1 - std::exp(-sigma * L)), 1e-12)
                    << to_string(kind);
            EXPECT_NEAR(r.alpha, 1 - std::exp(-sigma * L), 1e-12);
        }
    }
    // riemann (eq. (9)): a geometric series with its own closed form; the
    // error against the continuous model is O(σδ) and measured here.
    auto s = settings(IntegratorKind::riemann, SamplePoint::near, 0.3);
    s.background = bg;
    const RayResult r = Renderer(vol, tf, s).trace(x_ray(5));
    const double n = std::ceil(L / 0.3), d = L / n, t = std::exp(-sigma * d);
    for (int ch = 0; ch < 3; ++ch) {
        const double riemann = c[ch] * sigma * d * (1 - std::pow(t, n)) / (1 - t) + bg[ch] * std::pow(t, n);
        const double exact = bg[ch] * std::exp(-sigma * L) + c[ch] * (1 - std::exp(-sigma * L));
        EXPECT_NEAR(r.radiance[ch], riemann, 1e-12);
        EXPECT_GT(std::abs(riemann - exact), 1e-3 * c[ch]);  // first order: visibly off at δ = 0.3
        EXPECT_LT(std::abs(riemann - exact), sigma * d * c[ch]);
    }
}

TEST(Integrators, AbsorptionOfALinearRampMatchesClosedForm) {
    // v(x) = x along the ray, σ(v) = a + b·v: T = exp(−(aL + bL²/2)), eq. (21).
    const Volume vol = make_volume(9, 3, 3, [](double x, double, double) { return x; });
    const double a = 0.05, b = 0.04, L = 8.0;
    const auto tf = extinction_tf({{0.0, a}, {8.0, a + 8.0 * b}}, {1, 1, 1});
    const Ray ray{{-2.0, 1.0, 1.0}, {1.0, 0.0, 0.0}};
    const double exact = std::exp(-(a * L + b * L * L / 2));
    for (auto kind : kAll) {
        for (auto sp : {SamplePoint::near, SamplePoint::mid}) {
            auto s = settings(kind, sp, 0.5);
            s.model = Model::absorption;
            const RayResult r = Renderer(vol, tf, s).trace(ray);
            for (int ch = 0; ch < 3; ++ch) {
                if (kind == IntegratorKind::reference || sp == SamplePoint::mid ||
                    kind == IntegratorKind::preintegrated || kind == IntegratorKind::preintegrated_simple) {
                    // the midpoint rule integrates a linear σ exactly
                    EXPECT_NEAR(r.radiance[ch], exact, 1e-12) << to_string(kind);
                } else {
                    // near point: optical depth short by b·δ·L/2
                    EXPECT_NEAR(r.radiance[ch], exact * std::exp(b * 0.5 * L / 2), 1e-12) << to_string(kind);
                }
            }
        }
    }
}

namespace {

// A smooth field and TF for convergence studies: σ and c vary along the ray.
struct Smooth {
    Volume vol = make_volume(24, 24, 24, [](double x, double y, double z) {
        return 0.5 + 0.4 * std::sin(0.3 * x + 0.2 * y) * std::cos(0.25 * z);
    });
    TransferFunction tf = [] {
        TransferFunction t;
        t.alpha_kind = TransferFunction::Alpha::extinction;
        t.alpha_points = {{0.0, 0.0}, {1.0, 0.6}};
        t.color_points = {{0.0, {1.0, 0.2, 0.0}}, {1.0, {0.0, 0.4, 1.0}}};
        return t;
    }();
    Ray ray{{-5.0, 2.3, 1.7}, normalize(Vec3{1.0, 0.8, 0.6})};
};

double slope(const std::vector<double>& h, const std::vector<double>& err) {
    // least-squares slope of log(err) over log(h)
    double sx = 0, sy = 0, sxx = 0, sxy = 0;
    const double n = static_cast<double>(h.size());
    for (std::size_t i = 0; i < h.size(); ++i) {
        const double x = std::log(h[i]), y = std::log(err[i]);
        sx += x, sy += y, sxx += x * x, sxy += x * y;
    }
    return (n * sxy - sx * sy) / (n * sxx - sx * sx);
}

double convergence_order(IntegratorKind k, SamplePoint sp) {
    const Smooth sc;
    auto ref_s = settings(IntegratorKind::reference);
    ref_s.reference_tolerance = 1e-9;
    const RayResult ref = Renderer(sc.vol, sc.tf, ref_s).trace(sc.ray);
    std::vector<double> hs, errs;
    for (double h : {1.0, 0.5, 0.25, 0.125, 0.0625}) {
        const RayResult r = Renderer(sc.vol, sc.tf, settings(k, sp, h)).trace(sc.ray);
        double e = 0;
        for (int c = 0; c < 3; ++c) e = std::max(e, std::abs(r.radiance[c] - ref.radiance[c]));
        hs.push_back(h);
        errs.push_back(e);
    }
    return slope(hs, errs);
}

}  // namespace

TEST(Integrators, ConvergenceOrders) {
    EXPECT_NEAR(convergence_order(IntegratorKind::riemann, SamplePoint::near), 1.0, 0.2);
    EXPECT_NEAR(convergence_order(IntegratorKind::riemann, SamplePoint::mid), 1.0, 0.2);
    EXPECT_NEAR(convergence_order(IntegratorKind::alpha, SamplePoint::near), 1.0, 0.2);
    EXPECT_NEAR(convergence_order(IntegratorKind::alpha, SamplePoint::mid), 2.0, 0.2);
    EXPECT_GE(convergence_order(IntegratorKind::preintegrated, SamplePoint::near), 1.8);
    EXPECT_NEAR(convergence_order(IntegratorKind::preintegrated_simple, SamplePoint::near), 1.0, 0.2);
}

TEST(Integrators, ReferenceMeetsItsToleranceOnJumpsAndKinks) {
    // A TF with a jump and a spike: the reference must agree with a very
    // fine alpha-mid sum (error O(δ²) away from the jump, O(δ) at it).
    const Smooth sc;
    TransferFunction tf = sc.tf;
    tf.alpha_points = {{0.0, 0.0},  {0.45, 0.1}, {0.45, 1.5}, {0.5, 0.2},
                       {0.52, 3.0}, {0.54, 0.2}, {1.0, 0.4}};
    auto rs = settings(IntegratorKind::reference);
    const RayResult ref = Renderer(sc.vol, tf, rs).trace(sc.ray);
    const RayResult fine =
        Renderer(sc.vol, tf, settings(IntegratorKind::alpha, SamplePoint::mid, 1e-4)).trace(sc.ray);
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(ref.radiance[c], fine.radiance[c], 2e-5);
    EXPECT_NEAR(ref.alpha, fine.alpha, 2e-5);
}

TEST(Integrators, FrontToBackEqualsBackToFront) {
    const Smooth sc;
    for (auto kind : kAll)
        for (auto sp : {SamplePoint::near, SamplePoint::mid})
            for (auto model : {Model::emission_absorption, Model::absorption, Model::emission}) {
                auto f = settings(kind, sp, 0.37);
                f.model = model;
                f.background = Rgb{0.3, 0.6, 0.9};
                auto b = f;
                b.order = Order::back_to_front;
                const RayResult rf = Renderer(sc.vol, sc.tf, f).trace(sc.ray);
                const RayResult rb = Renderer(sc.vol, sc.tf, b).trace(sc.ray);
                for (int c = 0; c < 3; ++c)
                    EXPECT_LE(std::abs(rf.radiance[c] - rb.radiance[c]),
                              1e-5 * std::max(1.0, std::abs(rb.radiance[c])));
                EXPECT_NEAR(rf.alpha, rb.alpha, 1e-12);
            }
}

TEST(Integrators, TerminationDropsTheRestAndTheBackground) {
    const Volume vol = make_volume(11, 3, 3, [](double, double, double) { return 1.0; });
    const double sigma = 1.0;
    const auto tf = extinction_tf({{0.0, sigma}}, {1, 1, 1});
    auto s = settings(IntegratorKind::alpha, SamplePoint::near, 0.5);
    s.termination = 0.05;
    s.background = Rgb{100, 100, 100};
    const RayResult r = Renderer(vol, tf, s).trace({{-1.0, 1.0, 1.0}, {1.0, 0.0, 0.0}});
    // T after k segments = e^{−σ·0.5·k}; the first k with T < 0.05 is k = 6.
    const double T = std::exp(-sigma * 0.5 * 6);
    EXPECT_NEAR(r.alpha, 1 - T, 1e-12);
    EXPECT_NEAR(r.radiance[0], 1 - T, 1e-12);  // c (1 − T): no background, no later segments
    s.termination = 0.0;
    const RayResult full = Renderer(vol, tf, s).trace({{-1.0, 1.0, 1.0}, {1.0, 0.0, 0.0}});
    EXPECT_GT(full.radiance[0], r.radiance[0] + 1e-3);
}

TEST(Integrators, EmissionModelHasNoOpacityAndAddsTheBackground) {
    const Volume vol = make_volume(5, 5, 5, [](double, double, double) { return 1.0; });
    const auto tf = extinction_tf({{0.0, 0.5}}, {1.0, 2.0, 0.0});
    for (auto kind : kAll) {
        auto s = settings(kind);
        s.model = Model::emission;
        s.background = Rgb{0.25, 0.25, 0.25};
        const RayResult r = Renderer(vol, tf, s).trace(x_ray(5));
        EXPECT_DOUBLE_EQ(r.alpha, 0.0);
        EXPECT_NEAR(r.radiance[1], 0.25 + 2.0 * 0.5 * 4.0, 1e-12);  // eq. (5): I_bg + ∫ σ c dt
    }
}

TEST(Integrators, MissingAndGrazingRaysSeeTheBackground) {
    const Volume vol = make_volume(5, 5, 5, [](double, double, double) { return 1.0; });
    const auto tf = extinction_tf({{0.0, 5.0}}, {1, 1, 1});
    auto s = settings(IntegratorKind::alpha);
    s.background = Rgb{0.5, 0.5, 0.5};
    const Renderer r(vol, tf, s);
    EXPECT_EQ(r.trace({{-1, 10, 2}, {1, 0, 0}}).alpha, 0.0);        // misses
    EXPECT_EQ(r.trace({{-1, 2, 2}, {-1, 0, 0}}).radiance[0], 0.5);  // box behind the camera (t < 0)
    const RayResult corner = r.trace({{-1, 1, 2}, normalize(Vec3{1, -1, 0})});  // touches one edge: L = 0
    EXPECT_EQ(corner.alpha, 0.0);
    EXPECT_GT(r.trace({{-1, 0, 2}, {1, 0, 0}}).alpha, 0.9);  // lies in a face: sees it
    EXPECT_GT(r.trace({{2, 2, 2}, {1, 0, 0}}).alpha, 0.9);   // starts inside: t_near = 0
}

TEST(Integrators, PreclassifiedGridsRenderWithEveryIntegrator) {
    const Volume density = make_volume(5, 5, 5, [](double, double, double) { return 0.7; });
    Volume color({5, 5, 5}, DType::f32, 3);
    for (std::int64_t k = 0; k < 5; ++k)
        for (std::int64_t j = 0; j < 5; ++j)
            for (std::int64_t i = 0; i < 5; ++i) {
                color.set_value(i, j, k, 0.9, 0);
                color.set_value(i, j, k, 0.5, 1);
                color.set_value(i, j, k, 0.2, 2);
            }
    // the grids hold float32: compare with the stored values
    const double T = std::exp(-double(0.7f) * 4.0);
    for (auto kind : {IntegratorKind::alpha, IntegratorKind::reference}) {
        const RayResult r = Renderer(density, color, settings(kind)).trace(x_ray(5));
        EXPECT_NEAR(r.radiance[0], double(0.9f) * (1 - T), 1e-12);
        EXPECT_NEAR(r.radiance[2], double(0.2f) * (1 - T), 1e-12);
    }
    EXPECT_GT(Renderer(density, color, settings(IntegratorKind::riemann)).trace(x_ray(5)).alpha, 0.9);
    auto mip = settings(IntegratorKind::alpha);
    mip.model = Model::mip;
    EXPECT_THROW(Renderer(density, color, mip), Error);
    EXPECT_THROW(Renderer(density, density, settings(IntegratorKind::alpha)),
                 Error);  // color needs 3 components
}

TEST(Integrators, MipOfOneBrightVoxelIsItsColor) {
    Volume vol = make_volume(7, 7, 7, [](double, double, double) { return 0.0; });
    vol.set_value(3, 4, 2, 10.0);
    TransferFunction tf = extinction_tf({{0.0, 0.0}}, {0, 0, 0});
    tf.color_points = {{0.0, {0, 0, 0}}, {10.0, {0.2, 0.4, 0.8}}};
    auto s = settings(IntegratorKind::alpha, SamplePoint::near, 0.5);
    s.model = Model::mip;
    // a ray through the voxel along z hits it at a segment end (z = 2 with t_near at z = 0)
    const RayResult r = Renderer(vol, tf, s).trace({{3.0, 4.0, -1.0}, {0, 0, 1}});
    EXPECT_DOUBLE_EQ(r.radiance[0], 0.2);
    EXPECT_DOUBLE_EQ(r.radiance[2], 0.8);
    EXPECT_DOUBLE_EQ(r.alpha, 1.0);
}

TEST(Integrators, MinipAndAverageProjections) {
    // v = x along the ray: min 0, max 8, trapezoidal mean 4 (exact for a linear v)
    Volume vol = make_volume(9, 3, 3, [](double x, double, double) { return x; });
    TransferFunction tf = extinction_tf({{0.0, 0.0}}, {0, 0, 0});
    tf.color_points = {{0.0, {0, 0, 0}}, {8.0, {0.8, 0.4, 1.6}}};
    const Ray ray{{-2.0, 1.0, 1.0}, {1.0, 0.0, 0.0}};
    auto s = settings(IntegratorKind::alpha, SamplePoint::near, 0.7);
    s.model = Model::average;
    EXPECT_NEAR(Renderer(vol, tf, s).trace(ray).radiance[0], 0.4, 1e-12);
    s.model = Model::minip;
    EXPECT_DOUBLE_EQ(Renderer(vol, tf, s).trace(ray).radiance[2], 0.0);
    s.model = Model::mip;
    EXPECT_DOUBLE_EQ(Renderer(vol, tf, s).trace(ray).radiance[2], 1.6);
    // one dark voxel in a bright volume: minip shows its color
    Volume bright = make_volume(7, 7, 7, [](double, double, double) { return 8.0; });
    bright.set_value(3, 4, 2, 2.0);
    s.model = Model::minip;
    s.step = 0.5;
    const RayResult r = Renderer(bright, tf, s).trace({{3.0, 4.0, -1.0}, {0, 0, 1}});
    EXPECT_DOUBLE_EQ(r.radiance[0], 0.2);
    EXPECT_DOUBLE_EQ(r.alpha, 1.0);
}

TEST(Integrators, JitterIsDeterministicOffByDefaultAndAveragesOut) {
    const Smooth sc;
    const Bounds b = volume_bounds(sc.vol);
    const Camera cam = Camera::orbit(30, 20, 2.5, b.center, b.radius);
    auto render = [&](bool jitter, std::uint32_t seed, IntegratorKind k = IntegratorKind::alpha,
                      int threads = 2) {
        auto s = settings(k, SamplePoint::near, 2.0);
        s.width = s.height = 16;
        s.jitter = jitter;
        s.jitter_seed = seed;
        s.threads = threads;
        return Renderer(sc.vol, sc.tf, s).render(cam);
    };
    const Image plain = render(false, 0), a = render(true, 7), b1 = render(true, 7, IntegratorKind::alpha, 1);
    EXPECT_EQ(a.rgba, b1.rgba);               // deterministic, whatever the thread count
    EXPECT_NE(a.rgba, plain.rgba);            // it moves the samples
    EXPECT_NE(a.rgba, render(true, 8).rgba);  // and the seed matters
    // Averaged over seeds, the jittered sums approach the reference far better
    // than the fixed near-point sum (a random offset is unbiased for the optical depth).
    const Image ref = render(false, 0, IntegratorKind::reference);
    std::vector<double> mean(a.rgba.size(), 0.0);
    const int seeds = 32;
    for (int k = 0; k < seeds; ++k) {
        const Image img = render(true, static_cast<std::uint32_t>(k));
        for (std::size_t i = 0; i < mean.size(); ++i) mean[i] += img.rgba[i] / seeds;
    }
    double e_plain = 0, e_mean = 0;
    for (std::size_t i = 0; i < mean.size(); ++i) {
        if (i % 4 == 3) continue;
        e_plain += std::pow(plain.rgba[i] - ref.rgba[i], 2);
        e_mean += std::pow(mean[i] - ref.rgba[i], 2);
    }
    EXPECT_LT(e_mean, 0.25 * e_plain);
}
