// The differentiable renderer: its forward pass is the renderer's, and every
// backward pass matches central finite differences in double precision (the
// adjoint check harness; tolerances per case below).
#include <algorithm>
#include <cmath>
#include <cstdio>
#include <functional>
#include <random>

#include <gtest/gtest.h>

#include "fathom/differentiable.h"
#include "fathom/error.h"
#include "fathom/render.h"

#include "render/renderer_impl.h"
#include "synthetic.h"
#include "test_util.h"

namespace fathom {
namespace {

constexpr IntegratorKind kIntegrators[] = {IntegratorKind::riemann, IntegratorKind::alpha,
                                           IntegratorKind::preintegrated_simple,
                                           IntegratorKind::preintegrated};

Volume random_grid(std::array<std::int64_t, 3> dims, int comps, double lo, double hi, std::mt19937& rng) {
    Volume v(dims, DType::f64, comps);
    std::uniform_real_distribution<double> u(lo, hi);
    double* p = v.data<double>();
    for (std::int64_t i = 0; i < v.num_nodes() * comps; ++i) p[i] = u(rng);
    v.set_spacing({1.0, 0.8, 1.2});
    v.set_origin({-1, 0.5, 2});
    return v;
}

/// Random density (σ in [lo, hi]) and color grids on one lattice.
struct Grids {
    Volume density, color;
};
Grids random_grids(std::array<std::int64_t, 3> dims, double lo, double hi, std::mt19937& rng) {
    Grids g{random_grid(dims, 1, lo, hi, rng), random_grid(dims, 3, 0.0, 1.0, rng)};
    return g;
}

/// Rays of a small orbit camera's image (all of them meet the box or its
/// neighbourhood), with random adjoints.
struct Problem {
    std::vector<Ray> rays;
    std::vector<RayAdjoint> adj;
};

Problem make_problem(const Volume& lattice, int size, std::mt19937& rng, double az = 30, double el = 20) {
    const Bounds b = volume_bounds(lattice);
    const Camera cam = Camera::orbit(az, el, 2.5, b.center, b.radius);
    Problem p;
    std::uniform_real_distribution<double> u(-1, 1);
    for (int y = 0; y < size; ++y)
        for (int x = 0; x < size; ++x) {
            p.rays.push_back(cam.generate(x, y, size, size));
            p.adj.push_back({{u(rng), u(rng), u(rng)}, u(rng)});
        }
    return p;
}

/// L = Σ_rays adjoint · (I, α).
double loss(const DiffRenderer& r, const Problem& p);

/// The loss with sample k of `v` moved by h, the renderer made by make().
template <class Make>
std::function<double(std::size_t, double)> perturbed(Volume& v, const Problem& p, Make make) {
    return [&v, &p, make](std::size_t k, double h) {
        double& x = v.data<double>()[k];
        const double keep = x;
        x += h;
        const double L = loss(make(), p);
        x = keep;
        return L;
    };
}

double loss(const DiffRenderer& r, const Problem& p) {
    double L = 0;
    for (std::size_t i = 0; i < p.rays.size(); ++i) {
        const RayResult f = r.forward(p.rays[i]);
        for (int c = 0; c < 3; ++c) L += p.adj[i].radiance[c] * f.radiance[c];
        L += p.adj[i].alpha * f.alpha;
    }
    return L;
}

Gradients analytic(const DiffRenderer& r, const Problem& p) {
    Gradients g = r.make_gradients();
    for (std::size_t i = 0; i < p.rays.size(); ++i) r.backward(p.rays[i], r.forward(p.rays[i]), p.adj[i], g);
    return g;
}

/// Compares analytic gradients with central differences of `perturbed(k, ±h)`
/// for every parameter k: max |a − fd| / max(max |fd|, floor) ≤ tol.
void check_against_fd(const std::vector<double>& analytic_grad,
                      const std::function<double(std::size_t, double)>& L, double h, double tol,
                      const std::string& what) {
    double worst = 0, scale = 1e-12;
    std::vector<double> fd(analytic_grad.size());
    for (std::size_t k = 0; k < analytic_grad.size(); ++k) {
        fd[k] = (L(k, h) - L(k, -h)) / (2 * h);
        scale = std::max(scale, std::abs(fd[k]));
    }
    std::size_t at = 0;
    for (std::size_t k = 0; k < fd.size(); ++k) {
        const double e = std::abs(analytic_grad[k] - fd[k]);
        if (e > worst) {
            worst = e;
            at = k;
        }
    }
    std::printf("[gradcheck] %-60s max rel. error %.2e (tolerance %.0e)\n", what.c_str(), worst / scale, tol);
    EXPECT_LE(worst / scale, tol) << what << ": parameter " << at << " analytic " << analytic_grad[at]
                                  << " fd " << fd[at] << " (scale " << scale << ")";
    EXPECT_GT(scale, 1e-9) << what << ": the loss does not depend on the parameters";
}

RenderSettings diff_settings(IntegratorKind k, Model m = Model::emission_absorption) {
    RenderSettings s;
    s.integrator = k;
    s.model = m;
    s.termination = 0.0;  // the loss must be smooth: no early termination
    s.step = 0.7;
    s.background = Rgb{0.2, 0.3, 0.4};
    s.threads = 1;
    return s;
}

/// FD tolerance: the point quadratures are closed forms (1e−6 leaves room
/// for the differences' own truncation and rounding at h = 1e−5); the
/// pre-integrated ones differentiate a Gauss–Legendre quadrature whose
/// sub-interval count steps with the optical depth (1e−5).
double tolerance(IntegratorKind k) {
    return k == IntegratorKind::preintegrated ? 1e-5 : 1e-6;
}

void check_grids(IntegratorKind k, Model m, double sigma_lo, double sigma_hi, unsigned seed, double tol = 0) {
    if (tol == 0) tol = tolerance(k);
    std::mt19937 rng(seed);
    auto [density, color] = random_grids({3, 4, 3}, sigma_lo, sigma_hi, rng);
    const RenderSettings s = diff_settings(k, m);
    const Problem p = make_problem(density, 5, rng);
    const Gradients g = analytic(DiffRenderer(density, color, s), p);
    const std::string what = std::string(to_string(k)) + "/" + std::string(to_string(m));
    auto make = [&] { return DiffRenderer(density, color, s); };
    auto perturb = [&](Volume& v) { return perturbed(v, p, make); };
    check_against_fd(g.density, perturb(density), 1e-5, tol, what + " density");
    // The radiance is linear in the color: a large step makes the
    // differences exact up to rounding (small ones drown tiny gradients of
    // nearly empty rays in the loss's rounding).
    if (m != Model::absorption) check_against_fd(g.color, perturb(color), 0.1, tol, what + " color");
}

TEST(Differentiable, GridGradientsMatchFiniteDifferences) {
    unsigned seed = 1;
    for (IntegratorKind k : kIntegrators)
        for (Model m : {Model::emission_absorption, Model::absorption, Model::emission})
            check_grids(k, m, 0.0, 1.5, seed++);
}

TEST(Differentiable, NearlyOpaqueAndNearlyEmptyRays) {
    // σ ~ 20/world unit over ~4 units: T ~ e^{−80} (no division by T or by
    // 1 − α anywhere); σ ~ 1e−7: α ~ 1e−7. Opaque rays: 1e−5 for every
    // integrator, since most of their gradients are ~1e−5 of the loss and
    // the differences' rounding (1e−16·L/h) is ~1e−6 of them.
    unsigned seed = 100;
    for (IntegratorKind k : kIntegrators) {
        check_grids(k, Model::emission_absorption, 15.0, 25.0, seed++, 1e-5);
        check_grids(k, Model::emission_absorption, 0.0, 2e-7, seed++);
    }
}

void check_scalar(IntegratorKind k, Model m, bool associated, TransferFunction::Alpha kind, unsigned seed) {
    std::mt19937 rng(seed);
    Volume vol = random_grid({3, 3, 4}, 1, 0.0, 1.0, rng);
    TransferFunction tf;
    tf.alpha_kind = kind;
    tf.associated = associated;
    const bool opacity = kind == TransferFunction::Alpha::opacity;
    tf.alpha_points = {{0.1, opacity ? 0.05 : 0.1},
                       {0.35, opacity ? 0.6 : 1.5},
                       {0.6, opacity ? 0.2 : 0.4},
                       {0.9, opacity ? 0.8 : 2.0}};
    tf.color_points = {{0.2, {0.9, 0.1, 0.2}}, {0.5, {0.2, 0.8, 0.3}}, {0.8, {0.3, 0.2, 0.9}}};
    RenderSettings s = diff_settings(k, m);
    const Problem p = make_problem(vol, 5, rng, 50, -25);
    const Gradients g = analytic(DiffRenderer(vol, tf, s), p);
    const std::string what = std::string(to_string(k)) + "/" + std::string(to_string(m)) +
                             (associated ? "/emission-tf" : "/color-tf") +
                             (opacity ? "/opacity" : "/extinction");
    const double tol = tolerance(k);
    check_against_fd(g.scalar, perturbed(vol, p, [&] { return DiffRenderer(vol, tf, s); }), 1e-6, tol,
                     what + " voxels");
    if (m == Model::emission && associated) {  // σ has no part in it: q alone emits
        for (double x : g.tf_alpha) EXPECT_EQ(x, 0.0) << what;
    } else {
        check_against_fd(
            g.tf_alpha,
            [&](std::size_t idx, double h) {
                TransferFunction t = tf;
                t.alpha_points[idx].second += h;
                return loss(DiffRenderer(vol, t, s), p);
            },
            1e-6, tol, what + " tf alpha");
    }
    if (m != Model::absorption) {
        std::vector<double> gc;
        for (const Rgb& c : g.tf_color) gc.insert(gc.end(), c.begin(), c.end());
        check_against_fd(
            gc,
            [&](std::size_t idx, double h) {
                TransferFunction t = tf;
                t.color_points[idx / 3].second[idx % 3] += h;
                return loss(DiffRenderer(vol, t, s), p);
            },
            0.1, tol, what + " tf color");  // linear in the color, as above
    }
}

TEST(Differentiable, ScalarVolumeAndTransferFunctionGradientsMatchFiniteDifferences) {
    unsigned seed = 200;
    for (IntegratorKind k : kIntegrators) {
        check_scalar(k, Model::emission_absorption, false, TransferFunction::Alpha::opacity, seed++);
        check_scalar(k, Model::emission_absorption, false, TransferFunction::Alpha::extinction, seed++);
        check_scalar(k, Model::absorption, false, TransferFunction::Alpha::extinction, seed++);
        check_scalar(k, Model::emission, true, TransferFunction::Alpha::extinction, seed++);
        check_scalar(k, Model::emission_absorption, true, TransferFunction::Alpha::opacity, seed++);
    }
}

TEST(Differentiable, ForwardIsTheRenderersResult) {
    std::mt19937 rng(7);
    auto [density, color] = random_grids({5, 4, 6}, 0.0, 1.0, rng);
    Volume vol = random_grid({5, 4, 6}, 1, 0.0, 1.0, rng);
    const TransferFunction tf = TransferFunction::preset("ct-bone", {0.0, 1.0});
    const Problem p = make_problem(density, 8, rng);
    for (IntegratorKind k : kIntegrators)
        for (SamplePoint sp : {SamplePoint::near, SamplePoint::mid}) {
            RenderSettings s;
            s.integrator = k;
            s.sample_point = sp;
            s.skip_empty = false;
            s.simd = false;
            s.termination = 0.05;
            const Renderer rg(density, color, s), rs(vol, tf, s);
            const DiffRenderer dg(density, color, s), ds(vol, tf, s);
            for (const Ray& ray : p.rays) {
                const RayResult a = rg.trace(ray), b = dg.forward(ray);
                EXPECT_EQ(a.radiance, b.radiance);
                EXPECT_EQ(a.alpha, b.alpha);
                const RayResult c = rs.trace(ray), d = ds.forward(ray);
                EXPECT_EQ(c.radiance, d.radiance);
                EXPECT_EQ(c.alpha, d.alpha);
            }
        }
}

TEST(Differentiable, EarlyTerminationGradientIsThatOfTheTerminatedSum) {
    // With termination the backward pass stops where the forward pass did:
    // its gradient is that of the computed (terminated) function, checked by
    // differences small enough not to move the stopping segment.
    std::mt19937 rng(11);
    auto [density, color] = random_grids({3, 4, 3}, 2.0, 4.0, rng);
    RenderSettings s = diff_settings(IntegratorKind::alpha);
    s.termination = 0.05;
    const Problem p = make_problem(density, 4, rng);
    const Gradients g = analytic(DiffRenderer(density, color, s), p);
    check_against_fd(g.density, perturbed(density, p, [&] { return DiffRenderer(density, color, s); }), 1e-7,
                     1e-5, "alpha with termination");
}

TEST(Differentiable, ThreadedBatchesAreDeterministicAndMatchSerial) {
    std::mt19937 rng(3);
    auto [density, color] = random_grids({6, 6, 6}, 0.0, 1.0, rng);
    const Problem p = make_problem(density, 12, rng);
    RenderSettings s = diff_settings(IntegratorKind::alpha);
    const DiffRenderer one(density, color, s);
    s.threads = 2;
    const DiffRenderer two(density, color, s);
    const auto f1 = one.forward(std::span<const Ray>(p.rays));
    const auto f2 = two.forward(std::span<const Ray>(p.rays));
    ASSERT_EQ(f1.size(), p.rays.size());
    for (std::size_t i = 0; i < f1.size(); ++i) {
        EXPECT_EQ(f1[i].radiance, f2[i].radiance);
        EXPECT_EQ(f1[i].radiance, one.forward(p.rays[i]).radiance);
    }
    Gradients serial = analytic(one, p);
    Gradients a = two.make_gradients(), b = two.make_gradients(), c = one.make_gradients();
    two.backward(p.rays, f2, p.adj, a);
    two.backward(p.rays, f2, p.adj, b);
    one.backward(p.rays, f1, p.adj, c);
    EXPECT_EQ(a.density, b.density);  // bit for bit, run to run
    EXPECT_EQ(a.color, b.color);
    EXPECT_EQ(c.density, serial.density);  // one thread: the one-ray calls in order
    for (std::size_t i = 0; i < a.density.size(); ++i)
        EXPECT_NEAR(a.density[i], serial.density[i], 1e-12 * (1 + std::abs(serial.density[i])));
}

TEST(Differentiable, SkippingEmptyDensityKeepsForwardAndOutsideGradients) {
    // Density exactly 0 at x < 10: the macrocells of 4 cells with mx = 0, 1 (nodes x = 0..8) are
    // empty; mx = 2 (nodes 8..12) is not. Also single zero nodes elsewhere (no empty macrocell).
    std::mt19937 rng(11);
    auto [density, color] = random_grids({20, 18, 17}, 0.05, 0.6, rng);
    double* d = density.data<double>();
    for (std::int64_t k = 0; k < 17; ++k)
        for (std::int64_t j = 0; j < 18; ++j)
            for (std::int64_t i = 0; i < 20; ++i)
                if (i < 10 || (i + j + k) % 7 == 0) d[i + 20 * (j + 18 * k)] = 0.0;
    for (const IntegratorKind k : kIntegrators) {
        SCOPED_TRACE(std::string(to_string(k)));
        const RenderSettings s = diff_settings(k);
        const DiffRenderer exact(density, color, s);
        DiffRenderer skipping(density, color, s);
        skipping.skip_empty_density(true);
        EXPECT_GT(skipping.empty_fraction(), 0.0);
        EXPECT_EQ(exact.empty_fraction(), 0.0);
        const Problem p = make_problem(density, 14, rng, 70, 10);
        Gradients ge = exact.make_gradients(), gs = skipping.make_gradients();
        for (std::size_t r = 0; r < p.rays.size(); ++r) {
            const RayResult fe = exact.forward(p.rays[r]), fs = skipping.forward(p.rays[r]);
            ASSERT_EQ(fe.radiance, fs.radiance) << "ray " << r;  // bit for bit
            ASSERT_EQ(fe.alpha, fs.alpha) << "ray " << r;
            exact.backward(p.rays[r], fe, p.adj[r], ge);
            skipping.backward(p.rays[r], fs, p.adj[r], gs);
        }
        // Nodes x ≥ 9 touch no empty macrocell's cells: the same gradient, bit for bit. Nodes
        // x ≤ 7 only touch skipped cells: none (x ≤ 6 pre-integrated, where a segment from cell 7
        // into cell 8 leaves the macrocell and is computed). x = 8 borders both.
        const bool point = k == IntegratorKind::riemann || k == IntegratorKind::alpha;
        const std::int64_t inside = point ? 7 : 6;
        std::size_t inside_nonzero = 0;
        for (std::int64_t n = 0; n < density.num_nodes(); ++n) {
            const std::int64_t x = n % 20;
            const auto u = static_cast<std::size_t>(n);
            if (x >= 9) {
                ASSERT_EQ(gs.density[u], ge.density[u]) << "node " << n;
                for (std::size_t c = 0; c < 3; ++c) ASSERT_EQ(gs.color[3 * u + c], ge.color[3 * u + c]);
            } else if (x <= inside) {
                ASSERT_EQ(gs.density[u], 0.0) << "node " << n;
                inside_nonzero += ge.density[u] != 0.0;
            }
        }
        EXPECT_GT(inside_nonzero, 0u) << "the exact gradient inside the empty region is not zero";
        skipping.skip_empty_density(false);
        EXPECT_EQ(skipping.empty_fraction(), 0.0);
    }
    // Scalar volumes: refused.
    Volume scalar = random_grid({4, 4, 4}, 1, 0.0, 1.0, rng);
    TransferFunction tf;
    tf.alpha_points = {{0.0, 0.1}, {1.0, 0.5}};
    tf.color_points = {{0.0, {1, 0, 0}}, {1.0, {0, 0, 1}}};
    DiffRenderer sr(scalar, tf, diff_settings(IntegratorKind::alpha));
    EXPECT_THROW(sr.skip_empty_density(true), Error);
}

TEST(Differentiable, ImageBackwardIsTheSumOfItsRays) {
    std::mt19937 rng(5);
    auto [density, color] = random_grids({4, 4, 4}, 0.0, 2.0, rng);
    RenderSettings s = diff_settings(IntegratorKind::preintegrated);
    s.width = 7;
    s.height = 5;
    s.jitter = true;
    const DiffRenderer r(density, color, s);
    const Bounds b = volume_bounds(density);
    const Camera cam = Camera::orbit(10, 35, 2.5, b.center, b.radius);
    std::vector<float> adj(7 * 5 * 4);
    std::uniform_real_distribution<float> u(-1, 1);
    for (float& a : adj) a = u(rng);
    Gradients img = r.make_gradients(), rays = r.make_gradients();
    r.backward(cam, adj, img);
    const Image fwd = r.render(cam);
    for (int y = 0; y < 5; ++y)
        for (int x = 0; x < 7; ++x) {
            const Ray ray = cam.generate(x, y, 7, 5);
            const double off = jitter_offset(x, y, s.jitter_seed);
            const RayResult f = r.forward(ray, off);
            EXPECT_FLOAT_EQ(fwd.pixel(x, y)[0], static_cast<float>(f.radiance[0]));
            const float* a = &adj[static_cast<std::size_t>((y * 7 + x) * 4)];
            r.backward(ray, f, {{a[0], a[1], a[2]}, a[3]}, rays, off);
        }
    for (std::size_t i = 0; i < img.density.size(); ++i)
        EXPECT_NEAR(img.density[i], rays.density[i], 1e-12 * (1 + std::abs(rays.density[i])));
}

TEST(Differentiable, RefusesWhatIsNotDifferentiable) {
    std::mt19937 rng(9);
    auto [density, color] = random_grids({3, 3, 3}, 0.0, 1.0, rng);
    RenderSettings s;
    s.integrator = IntegratorKind::reference;
    test::expect_error([&] { DiffRenderer(density, color, s); }, "differentiable rendering",
                       {"reference integrator is not differentiable"});
    s = {};
    s.model = Model::mip;
    test::expect_error([&] { DiffRenderer(density, color, s); }, "differentiable rendering",
                       {"'mip' is not differentiable"});
    s = {};
    s.shading.enabled = true;
    test::expect_error(
        [&] {
            DiffRenderer(density, TransferFunction::preset("ct-bone", {0, 1}), s);
        },
        "differentiable rendering", {"shading is not differentiable"});
    TransferFunction tf = TransferFunction::preset("ct-bone", {0, 1});
    tf.gradient_opacity_points = {{0, 0}, {1, 1}};
    test::expect_error([&] { DiffRenderer(density, tf, RenderSettings{}); }, "differentiable rendering",
                       {"gradient opacity"});
    test::expect_error([&] { DiffRenderer(density, density, RenderSettings{}); }, "color grid",
                       {"3 components"});
    const DiffRenderer r(density, color, RenderSettings{});
    Gradients g = r.make_gradients();
    Gradients empty;
    test::expect_error([&] { r.backward(Ray{}, RayResult{}, RayAdjoint{}, empty); }, "backward",
                       {"sizes", "make_gradients"});
    std::vector<float> wrong(3);
    test::expect_error([&] { r.backward(Camera{}, wrong, g); }, "backward", {"4 floats per pixel"});
}

}  // namespace
}  // namespace fathom
