// Cutting (crop box, clipping planes): the ray interval is clipped exactly
// and the uniform segment division applies to what is left.
#include <cmath>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/render.h"

#include "synthetic.h"

using namespace fathom;
using fathom::test::extinction_tf;
using fathom::test::make_volume;

namespace {

constexpr double kN = 21;  // nodes per axis: the box is [0, 20]³, centre 10
constexpr double kSigma = 0.13;
const Rgb kColor{0.9, 0.6, 0.3}, kBg{0.2, 0.3, 0.4};

// Renderers keep a reference to their volume: one that lives on.
const Volume& homogeneous() {
    static const Volume v = make_volume(21, 21, 21, [](double, double, double) { return 0.5; });
    return v;
}

RenderSettings settings(IntegratorKind k) {
    RenderSettings s;
    s.integrator = k;
    s.termination = 0.0;
    s.background = kBg;
    return s;
}

// I = I_bg·e^{−σL} + c(1 − e^{−σL}) (the homogeneous medium, eq. (6)).
Rgb closed_form(double L) {
    const double T = std::exp(-kSigma * L);
    return {kBg[0] * T + kColor[0] * (1 - T), kBg[1] * T + kColor[1] * (1 - T),
            kBg[2] * T + kColor[2] * (1 - T)};
}

RayResult trace(const RenderSettings& s, const Ray& r) {
    return Renderer(homogeneous(), extinction_tf({{0.0, kSigma}}, kColor), s).trace(r);
}

void expect_radiance(const RayResult& r, const Rgb& want, const std::string& what) {
    for (int c = 0; c < 3; ++c) EXPECT_NEAR(r.radiance[c], want[c], 1e-12) << what << " channel " << c;
}

const Ray kXRay{{-3.0, 10.25, 9.875}, {1.0, 0.0, 0.0}};  // chord 20
const Ray kZRay{{10.5, 9.25, 30.0}, {0.0, 0.0, -1.0}};   // chord 20, downwards

}  // namespace

TEST(Clipping, APlaneThroughTheCentreHalvesTheChord) {
    // the integrators exact on a homogeneous medium (preintegrated-simple
    // drops self-attenuation inside a segment, eq. (17))
    for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated, IntegratorKind::reference}) {
        RenderSettings s = settings(k);
        expect_radiance(trace(s, kXRay), closed_form(kN - 1), "unclipped " + std::string(to_string(k)));
        s.clip_planes = {{{10, 0, 0}, {1, 0, 0}}};  // keep x ≥ 10
        expect_radiance(trace(s, kXRay), closed_form((kN - 1) / 2), "keep the far half");
        s.clip_planes = {{{10, 0, 0}, {-2, 0, 0}}};  // keep x ≤ 10 (normals need not be unit)
        expect_radiance(trace(s, kXRay), closed_form((kN - 1) / 2), "keep the near half");
        s.clip_planes = {{{0, 0, 10}, {0, 0, 1}}};  // keep z ≥ 10 on a ray going down
        expect_radiance(trace(s, kZRay), closed_form((kN - 1) / 2), "z ray");
        // two planes: x in [5, 10]
        s.clip_planes = {{{10, 0, 0}, {-1, 0, 0}}, {{5, 0, 0}, {1, 0, 0}}};
        expect_radiance(trace(s, kXRay), closed_form(5), "slab");
    }
}

TEST(Clipping, RaysOnTheRemovedSideOrParallelOutsideSeeTheBackground) {
    RenderSettings s = settings(IntegratorKind::alpha);
    s.clip_planes = {{{0, 12, 0}, {0, 1, 0}}};  // keep y ≥ 12: the x ray (y = 10.25) is parallel, outside
    const RayResult r = trace(s, kXRay);
    EXPECT_EQ(r.alpha, 0.0);
    EXPECT_EQ(r.radiance, kBg);
    s.clip_planes = {{{0, 10, 0}, {0, 1, 0}}};  // parallel, inside: unchanged
    expect_radiance(trace(s, kXRay), closed_form(kN - 1), "parallel inside");
    s.clip_planes = {{{10, 0, 0}, {1, 0, 0}}, {{5, 0, 0}, {-1, 0, 0}}};  // x ≥ 10 and x ≤ 5: nothing
    EXPECT_EQ(trace(s, kXRay).alpha, 0.0);
}

TEST(Clipping, TheCropBoxClipsInWorldCoordinates) {
    Volume v = homogeneous();
    v.set_spacing({0.5, 2.0, 1.0});  // world box [0, 10] × [0, 40] × [0, 20]
    v.set_origin({1.0, -3.0, 0.0});
    RenderSettings s = settings(IntegratorKind::preintegrated);
    const TransferFunction tf = extinction_tf({{0.0, kSigma}}, kColor);
    const Ray ray{{-5.0, 7.0, 4.5}, {1.0, 0.0, 0.0}};  // world chord x ∈ [1, 11]
    expect_radiance(Renderer(v, tf, s).trace(ray), closed_form(10), "uncropped");
    s.crop = WorldBox{{3.0, -100, -100}, {7.5, 100, 100}};
    expect_radiance(Renderer(v, tf, s).trace(ray), closed_form(4.5), "cropped");
    s.crop = WorldBox{{3.0, 8.0, -100}, {7.5, 100, 100}};  // the ray's y = 7 is outside
    EXPECT_EQ(Renderer(v, tf, s).trace(ray).alpha, 0.0);
}

TEST(Clipping, TheSegmentGridCoversOnlyWhatIsLeft) {
    // riemann with the near sample point on a linear ramp: the clipped ray's
    // n = ceil(L/h) segments start at the clipping plane.
    const Volume ramp = make_volume(21, 21, 21, [](double x, double, double) { return x; });
    TransferFunction tf = extinction_tf({{0.0, 0.0}, {20.0, 0.2}}, {1, 1, 1});
    RenderSettings s = settings(IntegratorKind::riemann);
    s.model = Model::absorption;
    s.step = 3.0;
    s.clip_planes = {{{4, 0, 0}, {1, 0, 0}}};  // x ∈ [4, 20]: L = 16, n = 6, δ = 16/6
    const RayResult r = Renderer(ramp, tf, s).trace(kXRay);
    double depth = 0;
    for (int i = 0; i < 6; ++i) depth += 0.01 * (4.0 + i * 16.0 / 6.0) * (16.0 / 6.0);
    EXPECT_NEAR(r.alpha, 1 - std::exp(-depth), 1e-12);
}

TEST(Clipping, BadCutsAreRefused) {
    RenderSettings s;
    s.clip_planes = {{{0, 0, 0}, {0, 0, 0}}};
    EXPECT_THROW(s.validate(), Error);
    s.clip_planes = {{{0, 0, NAN}, {0, 0, 1}}};
    EXPECT_THROW(s.validate(), Error);
    s.clip_planes.assign(7, ClipPlane{{0, 0, 0}, {0, 0, 1}});
    EXPECT_THROW(s.validate(), Error);
    s.clip_planes.assign(6, ClipPlane{{0, 0, 0}, {0, 0, 1}});
    EXPECT_NO_THROW(s.validate());
    s.crop = WorldBox{{0, 0, 0}, {1, 0, 1}};
    EXPECT_THROW(s.validate(), Error);
}
