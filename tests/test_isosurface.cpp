// The isosurface model (src/integrate/isosurface.h): hit depth and normal on
// an analytic sphere, several iso-values composited with their opacities,
// misses, settings errors.
#include <cmath>
#include <cstring>
#include <random>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/render.h"

#include "integrate/isosurface.h"
#include "synthetic.h"

using namespace fathom;
using fathom::test::extinction_tf;
using fathom::test::make_volume;

namespace {

// f = R − |x − c| with the centre on a node: along lattice lines through
// the centre the trilinear field is exactly linear, so the surface f = 0 is
// the sphere of radius R there.
constexpr double kC = 40, kR = 30;
const Volume& sphere() {
    static const Volume v = make_volume(81, 81, 81, [](double x, double y, double z) {
        return kR - std::sqrt((x - kC) * (x - kC) + (y - kC) * (y - kC) + (z - kC) * (z - kC));
    });
    return v;
}

RenderSettings iso_settings(std::vector<IsoSurface> isos) {
    RenderSettings s;
    s.model = Model::isosurface;
    s.isosurfaces = std::move(isos);
    s.step = 0.7;
    s.shading.ambient = 0.0;
    s.shading.diffuse = 1.0;
    s.shading.specular = 0.0;
    return s;
}

RayResult trace(const RenderSettings& s, const Ray& r) {
    return Renderer(sphere(), extinction_tf({{0.0, 1.0}}, {1, 1, 1}), s).trace(r);
}

}  // namespace

TEST(Isosurface, HitDepthOnASphereMatchesItsRadius) {
    const RenderSettings s = iso_settings({{0.0, {1, 1, 1}, 1.0}});
    // Along the three axes through the centre, from both sides.
    for (int a = 0; a < 3; ++a)
        for (double sign : {1.0, -1.0}) {
            Vec3 o{kC, kC, kC}, d{0, 0, 0};
            o[a] = kC - sign * 55.0;
            d[a] = sign;
            const RayResult r = trace(s, {o, d});
            EXPECT_NEAR(r.first_hit, 55.0 - kR, 1e-3) << "axis " << a << " sign " << sign;
            // head light along the normal: the full diffuse color
            EXPECT_NEAR(r.radiance[0], 1.0, 1e-6);
            EXPECT_EQ(r.alpha, 1.0);
        }
    // Oblique rays: the trilinear field's surface is within 0.01 voxel of the
    // sphere (interpolation error of r ~ h²/(8r) per axis); the normal is radial.
    for (double b : {5.0, 12.0, 20.0}) {
        const Ray ray{{kC - 60.0, kC + b, kC + 0.3 * b}, {1, 0, 0}};
        const double off = std::hypot(b, 0.3 * b);
        const RayResult r = trace(s, ray);
        const double want = 60.0 - std::sqrt(kR * kR - off * off);
        EXPECT_NEAR(r.first_hit, want, 0.01) << b;
        // |n·v| with n radial at the hit and v = −x: sqrt(R² − b²)/R
        EXPECT_NEAR(r.radiance[0], std::sqrt(kR * kR - off * off) / kR, 2e-3) << b;
    }
}

TEST(Isosurface, SeveralIsoValuesCompositeFrontToBack) {
    // f = 0 is the sphere of radius 30, f = 10 the one of radius 20.
    RenderSettings s = iso_settings({{10.0, {0, 1, 0}, 1.0}, {0.0, {1, 0, 0}, 0.5}});
    const RayResult r = trace(s, {{kC - 55, kC, kC}, {1, 0, 0}});
    EXPECT_NEAR(r.radiance[0], 0.5, 1e-6);  // the outer, half transparent red
    EXPECT_NEAR(r.radiance[1], 0.5, 1e-6);  // then the inner green through it
    EXPECT_NEAR(r.first_hit, 25.0, 1e-3);
    EXPECT_EQ(r.alpha, 1.0);
    // A ray that misses both sees the background.
    s.background = Rgb{0.1, 0.2, 0.3};
    const RayResult miss = trace(s, {{kC - 55, kC + 35, kC}, {1, 0, 0}});
    EXPECT_EQ(miss.alpha, 0.0);
    EXPECT_EQ(miss.radiance, (Rgb{0.1, 0.2, 0.3}));
    EXPECT_TRUE(std::isinf(miss.first_hit));
}

TEST(Isosurface, SettingsAreChecked) {
    RenderSettings s;
    s.model = Model::isosurface;
    EXPECT_THROW(s.validate(), Error);  // no iso-value
    s.isosurfaces = {{0.5, {1, 1, 1}, 1.5}};
    EXPECT_THROW(s.validate(), Error);
    s.isosurfaces = {{NAN, {1, 1, 1}, 1.0}};
    EXPECT_THROW(s.validate(), Error);
    s.isosurfaces = {{0.5, {1, 1, 1}, 1.0}};
    EXPECT_NO_THROW(s.validate());
    EXPECT_EQ(parse_model("isosurface", "x"), Model::isosurface);
}

// The bisection keeps the corners of the last cell (CellCache): every value
// and every crossing are the bits of GridSampler's lookups, for each sample
// type, along rays that cross cells in every direction, with brackets down
// to a few ulp (the midpoint no longer splits them).
TEST(Isosurface, CachedCellsGiveTheSamplersBitsAndCrossings) {
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    const auto field = [](double x, double y, double z) {
        return 40.0 * std::sin(0.7 * x + 0.3 * y) + 3.0 * z;
    };
    int crossings = 0, tiny = 0;
    for (DType type : {DType::u8, DType::i16, DType::f32}) {
        Volume v({13, 11, 9}, type);
        for (std::int64_t k = 0; k < 9; ++k)
            for (std::int64_t j = 0; j < 11; ++j)
                for (std::int64_t i = 0; i < 13; ++i) {
                    const double f =
                        field(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k));
                    v.set_value(i, j, k, type == DType::f32 ? f : std::round(std::abs(f)));
                }
        visit_dtype(type, [&]<class T>(T*) {
            const GridSampler<T> g(v);
            for (int ray = 0; ray < 200; ++ray) {
                RaySpan sp{};
                sp.p0 = {12 * u(rng), 10 * u(rng), 8 * u(rng)};
                sp.dp = {u(rng) - 0.5, u(rng) - 0.5, u(rng) - 0.5};
                const auto plain = [&](double t) { return g(sp.at(t)); };
                // lookups in any order, near and far, repeated
                CellCache<T> cached(g, sp);
                for (int q = 0; q < 50; ++q) {
                    const double t = q % 7 == 3 ? 0.0 : 6.0 * (u(rng) - 0.5);
                    const double a = cached(t), b = plain(t);
                    ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "t " << t;
                }
                // crossings of the value at t = 0 between brackets of every size
                const double lo = -3.0 * u(rng), iso = plain(0.0) + (u(rng) - 0.5);
                for (double len : {4.0, 0.5, 1e-3, 1e-13}) {
                    const double hi = lo + len;
                    const bool below = plain(lo) < iso;
                    if ((plain(hi) < iso) == below) continue;
                    for (double tol : {1e-5, 0.0}) {
                        const double a = bisect_crossing(CellCache<T>(g, sp), lo, hi, tol, iso, below);
                        const double b = bisect_crossing(plain, lo, hi, tol, iso, below);
                        ASSERT_EQ(std::memcmp(&a, &b, sizeof a), 0) << "bracket " << lo << " + " << len;
                        ++crossings;
                        tiny += tol == 0.0 ? 1 : 0;
                    }
                }
            }
        });
    }
    EXPECT_GT(crossings, 300);
    EXPECT_GT(tiny, 150);
}
