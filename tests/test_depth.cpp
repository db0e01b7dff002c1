// Depth outputs: the expected termination depth and the first hit.
#include <cmath>
#include <cstring>

#include <gtest/gtest.h>

#include "fathom/io.h"
#include "fathom/render.h"

#include "synthetic.h"
#include "test_util.h"

using namespace fathom;
using fathom::test::extinction_tf;
using fathom::test::make_volume;

namespace {

const Volume& box() {
    static const Volume v = make_volume(21, 21, 21, [](double x, double, double) { return x; });
    return v;
}

RenderSettings depth_settings(IntegratorKind k, Order o = Order::front_to_back) {
    RenderSettings s;
    s.integrator = k;
    s.order = o;
    s.termination = 0.0;
    s.step = 0.02;
    s.depth_outputs = true;
    return s;
}

const Ray kRay{{-1.0, 10.25, 9.875}, {1.0, 0.0, 0.0}};  // enters at t = 1, leaves at t = 21

}  // namespace

TEST(Depth, ExpectedDepthOfAHomogeneousMediumMatchesTheClosedForm) {
    // termination density σ·e^{−σ(t − t0)} on [t0, t0 + L]:
    // E[t] = t0 + 1/σ − L·e^{−σL} / (1 − e^{−σL})
    const double sigma = 0.15, t0 = 1.0, L = 20.0;
    const double want = t0 + 1 / sigma - L * std::exp(-sigma * L) / (1 - std::exp(-sigma * L));
    const TransferFunction tf = extinction_tf({{0.0, sigma}}, {1, 1, 1});
    for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated})
        for (auto o : {Order::front_to_back, Order::back_to_front}) {
            const RayResult r = Renderer(box(), tf, depth_settings(k, o)).trace(kRay);
            EXPECT_NEAR(r.depth, want, 1e-3) << to_string(k) << " " << to_string(o);
            EXPECT_NEAR(r.first_hit, t0, 1e-12);
        }
}

TEST(Depth, FirstHitIsWhereOpacityStartsAndMissesAreInfinite) {
    // σ = 0 for v = x < 8, then positive: the first hit is at x = 8 (t = 9),
    // to within one segment.
    const TransferFunction tf = extinction_tf({{0.0, 0.0}, {8.0, 0.0}, {9.0, 0.5}}, {1, 1, 1});
    for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated}) {
        RenderSettings s = depth_settings(k);
        const RayResult r = Renderer(box(), tf, s).trace(kRay);
        EXPECT_NEAR(r.first_hit, 9.0, s.step + 1e-9) << to_string(k);
        EXPECT_GT(r.depth, r.first_hit);
        const RayResult miss = Renderer(box(), tf, s).trace({{-1.0, 30.0, 5.0}, {1.0, 0.0, 0.0}});
        EXPECT_TRUE(std::isinf(miss.depth));
        EXPECT_TRUE(std::isinf(miss.first_hit));
    }
    // An image carries them per pixel.
    RenderSettings s = depth_settings(IntegratorKind::alpha);
    s.width = s.height = 8;
    s.step = 0.5;
    const Bounds b = volume_bounds(box());
    const Image img = Renderer(box(), tf, s).render(Camera::orbit(0, 0, 3, b.center, b.radius));
    ASSERT_EQ(img.depth.size(), 64u);
    ASSERT_EQ(img.first_hit.size(), 64u);
    EXPECT_TRUE(std::isfinite(img.depth[27]));
    EXPECT_LE(img.first_hit[27], img.depth[27]);
}

TEST(Depth, AnOpaqueIsosurfaceHasItsHitAsExpectedDepth) {
    RenderSettings s;
    s.model = Model::isosurface;
    s.isosurfaces = {{7.5, {1, 1, 1}, 1.0}};
    s.depth_outputs = true;
    const RayResult r = Renderer(box(), extinction_tf({{0.0, 1.0}}, {1, 1, 1}), s).trace(kRay);
    EXPECT_NEAR(r.first_hit, 8.5, 1e-4);
    EXPECT_DOUBLE_EQ(r.depth, r.first_hit);
}

TEST(Depth, ExrCarriesTheDepthsAsExtraChannels) {
    const TransferFunction tf = extinction_tf({{0.0, 0.0}, {8.0, 0.0}, {9.0, 0.5}}, {1, 1, 1});
    RenderSettings s = depth_settings(IntegratorKind::alpha);
    s.width = s.height = 8;
    s.step = 0.5;
    const Bounds b = volume_bounds(box());
    const Image img = Renderer(box(), tf, s).render(Camera::orbit(20, 10, 3, b.center, b.radius));
    fathom::test::TempDir dir;
    write_image(dir / "d.exr", img);
    const Image back = read_exr(dir / "d.exr");
    EXPECT_EQ(back.rgba, img.rgba);
    ASSERT_EQ(back.depth.size(), img.depth.size());
    ASSERT_EQ(back.first_hit.size(), img.first_hit.size());
    bool some_inf = false, some_finite = false;
    for (std::size_t i = 0; i < img.depth.size(); ++i) {
        // Bit for bit, infinities (misses) included.
        EXPECT_EQ(std::memcmp(&back.depth[i], &img.depth[i], sizeof(float)), 0) << i;
        EXPECT_EQ(std::memcmp(&back.first_hit[i], &img.first_hit[i], sizeof(float)), 0) << i;
        some_inf = some_inf || std::isinf(img.depth[i]);
        some_finite = some_finite || std::isfinite(img.depth[i]);
    }
    EXPECT_TRUE(some_inf && some_finite);
    // Without depth outputs there are no such channels.
    Image plain = img;
    plain.depth.clear();
    plain.first_hit.clear();
    write_image(dir / "p.exr", plain);
    const Image p = read_exr(dir / "p.exr");
    EXPECT_TRUE(p.depth.empty());
    EXPECT_TRUE(p.first_hit.empty());
}
