// Exact empty-space skipping (src/render/empty_space.h): the zero test on
// transfer functions, the macrocell classification, and images that are
// bit-identical with skipping on and off for every integrator, model, order
// and medium it applies to.
#include <cmath>
#include <cstring>
#include <latch>
#include <limits>
#include <random>
#include <thread>

#include <gtest/gtest.h>

#include "fathom/render.h"

#include "integrate/preintegrated.h"
#include "integrate/simd_classify.h"
#include "render/empty_space.h"
#include "synthetic.h"

using namespace fathom;
using fathom::test::extinction_tf;
using fathom::test::make_volume;

namespace {

// Three soft blobs in a box whose cell counts are not multiples of 8, with
// anisotropic spacing: v ∈ [0, 1], 0 far from the blobs.
Volume blobs() {
    Volume v = make_volume(37, 29, 45, [](double x, double y, double z) {
        auto blob = [&](double cx, double cy, double cz, double r) {
            const double d = std::sqrt((x - cx) * (x - cx) + (y - cy) * (y - cy) + (z - cz) * (z - cz));
            return std::max(0.0, 1.0 - d / r);
        };
        return std::min(1.0, blob(10, 9, 12, 7) + blob(26, 18, 30, 9) + blob(18, 22, 38, 4));
    });
    v.set_spacing({1.0, 1.5, 0.8});
    return v;
}

// σ exactly 0 below v = 0.3, a ramp, a jump at 0.6; colors vary with v.
TransferFunction blob_tf(bool associated = false) {
    TransferFunction tf;
    tf.alpha_kind = TransferFunction::Alpha::extinction;
    tf.alpha_points = {{0.0, 0.0}, {0.3, 0.0}, {0.45, 0.8}, {0.6, 0.8}, {0.6, 2.5}, {1.0, 3.0}};
    tf.associated = associated;
    if (associated)  // q exactly 0 below 0.2 only: σ = 0 but q ≠ 0 on [0.2, 0.3]
        tf.color_points = {{0.0, {0, 0, 0}}, {0.2, {0, 0, 0}}, {0.5, {0.6, 0.3, 0.1}}, {1.0, {1, 1, 0.5}}};
    else
        tf.color_points = {{0.0, {0.2, 0.4, 0.9}}, {0.5, {0.9, 0.5, 0.2}}, {1.0, {1, 1, 1}}};
    return tf;
}

bool same_pixels(const Image& a, const Image& b) {
    return a.width == b.width && a.height == b.height && a.rgba.size() == b.rgba.size() &&
           std::memcmp(a.rgba.data(), b.rgba.data(), sizeof(float) * a.rgba.size()) == 0;
}

std::vector<Camera> cameras(const Volume& v) {
    return fathom::test::comparison_cameras(v);
}

RenderSettings base(IntegratorKind k, Model m, Order o) {
    RenderSettings s;
    s.width = s.height = 40;
    s.integrator = k;
    s.model = m;
    s.order = o;
    s.step = 0.7;
    s.threads = 2;
    return s;
}

// Renders with skipping off and on, by the renderer's choice of macrocells
// (2³ on the blobs) and by 4³; returns the number of differing images.
int compare_scalar(const Volume& v, const TransferFunction& tf, RenderSettings s) {
    int bad = 0;
    for (const Camera& cam : cameras(v)) {
        s.skip_empty = false;
        const Image off = Renderer(v, tf, s).render(cam);
        s.skip_empty = true;
        for (const std::uint64_t fine : {RenderSettings{}.fine_macrocells_max, std::uint64_t{0}}) {
            s.fine_macrocells_max = fine;
            if (!same_pixels(Renderer(v, tf, s).render(cam), off)) ++bad;
        }
    }
    return bad;
}

constexpr std::array<IntegratorKind, 4> kSkipping{IntegratorKind::riemann, IntegratorKind::alpha,
                                                  IntegratorKind::preintegrated,
                                                  IntegratorKind::preintegrated_simple};
constexpr std::array<Model, 3> kModels{Model::emission_absorption, Model::absorption, Model::emission};

}  // namespace

TEST(EmptySpace, ZeroOnFollowsPiecesAndJumps) {
    const PiecewiseLinear<1> f(
        {{0.0, {0.0}}, {1.0, {0.0}}, {2.0, {1.0}}, {3.0, {0.0}}, {3.0, {0.0}}, {4.0, {0.0}}, {4.0, {2.0}}});
    EXPECT_TRUE(f.zero_on(-5.0, 0.5));
    EXPECT_TRUE(f.zero_on(0.0, 0.999));
    EXPECT_FALSE(f.zero_on(0.5, 1.0));  // at v = 1 the rising piece is selected
    EXPECT_FALSE(f.zero_on(0.5, 1.5));
    EXPECT_FALSE(f.zero_on(2.5, 3.5));  // the falling piece ends at 3
    EXPECT_TRUE(f.zero_on(3.0, 3.999));
    EXPECT_FALSE(f.zero_on(3.5, 4.0));  // the jump at 4 to 2
    EXPECT_FALSE(f.zero_on(5.0, 9.0));  // beyond the end: 2
    EXPECT_FALSE(f.zero_on(NAN, 0.5));
    EXPECT_FALSE(f.zero_on(0.6, 0.5));
    EXPECT_FALSE(PiecewiseLinear<1>().zero_on(0.0, 1.0));
}

TEST(EmptySpace, MacrocellsAreEmptyOnlyWhereTheMediumIsZero) {
    const Volume v = blobs();
    const Classifier tf(blob_tf(), v.smallest_spacing());
    const EmptySpace es = EmptySpace::for_scalar(v, tf, Model::emission_absorption, 3, 2);
    ASSERT_TRUE(es.any());
    EXPECT_GT(es.empty_fraction(), 0.3);
    EXPECT_LT(es.empty_fraction(), 0.95);
    // Every node of an empty macrocell has σ = 0 (brute force over all nodes).
    for (std::int64_t k = 0; k < 45; ++k)
        for (std::int64_t j = 0; j < 29; ++j)
            for (std::int64_t i = 0; i < 37; ++i) {
                const Vec3 p{static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)};
                if (es.empty(es.macrocell(p))) {
                    ASSERT_EQ(tf.sigma(v.value(i, j, k)), 0.0) << i << " " << j << " " << k;
                }
            }
    // Projection modes have nothing to skip; an all-zero σ is all empty.
    EXPECT_FALSE(EmptySpace::for_scalar(v, tf, Model::mip, 3, 2).any());
    const Classifier none(extinction_tf({{0.0, 0.0}}, {1, 1, 1}), 1.0);
    EXPECT_DOUBLE_EQ(EmptySpace::for_scalar(v, none, Model::absorption, 2, 1).empty_fraction(), 1.0);
}

// The share of inactive blocks inside non-empty macrocells, by which the
// renderer keeps or drops the bits: one bright node at (8, 8, 8) of a 17³
// grid lies on the shared faces of 2 macrocells (4 cells) and 2 blocks
// (2 cells) per axis, so 8 macrocells holding 4³ blocks are non-empty and 8
// of those blocks active: 56 of 64 clear.
TEST(EmptySpace, InactiveShareCountsTheBlocksOfNonEmptyMacrocells) {
    const Classifier tf(blob_tf(), 1.0);  // σ = 0 below 0.3
    Volume v({17, 17, 17}, DType::f32);
    const auto share = [&] {
        const EmptySpace es = EmptySpace::for_scalar(v, tf, Model::emission_absorption, 2, 1);
        return es.inactive_share(simd::active_cells(v, 0.3, 1));
    };
    EXPECT_EQ(share(), 0.0);  // no non-empty macrocell
    v.set_value(8, 8, 8, 1.0);
    EXPECT_DOUBLE_EQ(share(), 56.0 / 64.0);
    v.set_value(9, 8, 8, 1.0);  // inside blocks 4 and macrocells 2 along x: nothing new
    EXPECT_DOUBLE_EQ(share(), 56.0 / 64.0);
    v.set_value(0, 0, 0, 1.0);  // macrocell (0, 0, 0) and its block (0, 0, 0): 7 of 8 more clear
    EXPECT_DOUBLE_EQ(share(), 63.0 / 72.0);
    for (std::int64_t k = 0; k < 17; ++k)
        for (std::int64_t j = 0; j < 17; ++j)
            for (std::int64_t i = 0; i < 17; ++i) v.set_value(i, j, k, 0.5);
    EXPECT_EQ(share(), 0.0);  // every block active
}

// The classification against brute force, both ways: a macrocell is empty
// exactly when all its nodes (shared faces included) are zero, for sample
// types, component counts, cell sizes and sizes with n − 1 a multiple of the
// cell size or not. Sparse non-zero nodes (one NaN among floats) make each
// misplaced row, column or slice change the answer somewhere.
TEST(EmptySpace, MacrocellRangesMatchBruteForce) {
    std::mt19937 rng(7);
    int checked = 0;
    for (DType type : {DType::u8, DType::i16, DType::f32})
        for (int comps : {1, 2})
            for (int shift : {2, 3})
                for (std::array<std::int64_t, 3> n :
                     {std::array<std::int64_t, 3>{17, 9, 25}, std::array<std::int64_t, 3>{23, 30, 13}}) {
                    Volume v(n, type, comps);
                    std::uniform_int_distribution<std::int64_t> pick(0, n[0] * n[1] * n[2] - 1);
                    for (int k = 0; k < 12; ++k) {
                        const std::int64_t at = pick(rng);
                        const double value = type == DType::f32 && k == 0 ? NAN : 3.0;
                        v.set_value(at % n[0], at / n[0] % n[1], at / (n[0] * n[1]), value);
                        v.set_value(pick(rng) % n[0], 0, 0, 5.0, comps - 1);  // other component
                    }
                    const EmptySpace es = EmptySpace::for_zeros(v, shift, 2);
                    const std::int64_t c = std::int64_t{1} << shift;
                    const std::array<std::int64_t, 3> md{(n[0] - 2) / c + 1, (n[1] - 2) / c + 1,
                                                         (n[2] - 2) / c + 1};
                    for (std::int64_t mz = 0; mz < md[2]; ++mz)
                        for (std::int64_t my = 0; my < md[1]; ++my)
                            for (std::int64_t mx = 0; mx < md[0]; ++mx) {
                                bool zero = true;
                                for (std::int64_t z = mz * c; z <= std::min(mz * c + c, n[2] - 1); ++z)
                                    for (std::int64_t y = my * c; y <= std::min(my * c + c, n[1] - 1); ++y)
                                        for (std::int64_t x = mx * c; x <= std::min(mx * c + c, n[0] - 1);
                                             ++x)
                                            zero = zero && v.value(x, y, z) == 0.0;
                                const Vec3 p{static_cast<double>(mx * c), static_cast<double>(my * c),
                                             static_cast<double>(mz * c)};
                                ASSERT_EQ(es.empty(es.macrocell(p)), zero)
                                    << static_cast<int>(type) << " comps " << comps << " shift " << shift
                                    << " cell " << mx << " " << my << " " << mz;
                                ++checked;
                            }
                }
    EXPECT_GT(checked, 1000);
}

TEST(EmptySpace, NanNodesAreNeverSkipped) {
    Volume v = make_volume(10, 10, 10, [](double, double, double) { return 0.0; });
    v.set_value(3, 3, 3, NAN);
    const Classifier tf(blob_tf(), 1.0);
    const EmptySpace es = EmptySpace::for_scalar(v, tf, Model::emission_absorption, 2, 1);
    EXPECT_FALSE(es.empty(es.macrocell({3, 3, 3})));
    EXPECT_TRUE(es.empty(es.macrocell({9, 9, 9})));
}

// The tests the skipping exists for: every image identical bit for bit.
TEST(EmptySpace, ScalarImagesAreBitIdenticalWithAndWithoutSkipping) {
    const Volume v = blobs();
    for (auto k : kSkipping)
        for (auto m : kModels)
            for (auto o : {Order::front_to_back, Order::back_to_front})
                EXPECT_EQ(compare_scalar(v, blob_tf(), base(k, m, o)), 0)
                    << to_string(k) << " " << to_string(m) << " " << to_string(o);
}

// Pixels whose bounds hold no non-empty macrocell take the background
// without a ray (Renderer::Impl::empty_rays_see_background): the same bits as
// compositing nothing, but where it would differ: a −0 component (which
// compositing front to back turns into +0 inside the volume's outline, not
// outside it) and the average model (tf.color(0) inside it).
TEST(EmptySpace, PixelsOutsideTheBoundsKeepTheBackgroundBitForBit) {
    const Volume v = blobs();
    for (const Rgb& bg : {Rgb{0.2, 0.3, 0.4}, Rgb{0.2, -0.0, 0.4}, Rgb{-0.0, -0.0, -0.0}})
        for (auto m : {Model::emission_absorption, Model::average, Model::mip})
            for (auto o : {Order::front_to_back, Order::back_to_front}) {
                RenderSettings s = base(IntegratorKind::alpha, m, o);
                s.background = bg;
                EXPECT_EQ(compare_scalar(v, blob_tf(), s), 0)
                    << to_string(m) << " " << to_string(o) << " background " << bg[0] << "," << bg[1] << ","
                    << bg[2];
            }
}

TEST(EmptySpace, AssociatedEmissionJitterAndMidpointsAreBitIdentical) {
    const Volume v = blobs();
    for (auto k : kSkipping)
        for (auto m : kModels) {
            RenderSettings s = base(k, m, Order::front_to_back);
            EXPECT_EQ(compare_scalar(v, blob_tf(true), s), 0) << to_string(k) << " " << to_string(m);
        }
    for (auto k : {IntegratorKind::riemann, IntegratorKind::alpha}) {
        RenderSettings s = base(k, Model::emission_absorption, Order::front_to_back);
        s.jitter = true;
        s.jitter_seed = 7;
        EXPECT_EQ(compare_scalar(v, blob_tf(), s), 0) << to_string(k) << " jitter";
        s.jitter = false;
        s.sample_point = SamplePoint::mid;
        s.step = 0.25;
        EXPECT_EQ(compare_scalar(v, blob_tf(), s), 0) << to_string(k) << " mid";
    }
}

TEST(EmptySpace, PreclassifiedGridImagesAreBitIdentical) {
    const Volume shape = blobs();
    Volume density = make_volume(37, 29, 45, [&](double x, double y, double z) {
        const double s = shape.value(static_cast<std::int64_t>(x), static_cast<std::int64_t>(y),
                                     static_cast<std::int64_t>(z));
        return s > 0.25 ? 2.0 * s : 0.0;
    });
    density.set_spacing({1.0, 1.5, 0.8});
    Volume color({37, 29, 45}, DType::f32, 3);
    color.set_spacing({1.0, 1.5, 0.8});
    for (std::int64_t k = 0; k < 45; ++k)
        for (std::int64_t j = 0; j < 29; ++j)
            for (std::int64_t i = 0; i < 37; ++i)
                for (int c = 0; c < 3; ++c)
                    color.set_value(i, j, k, 0.1 + 0.02 * static_cast<double>((i + c * j) % 40), c);
    ASSERT_TRUE(EmptySpace::for_zeros(density, 3, 2).any());
    for (auto k : kSkipping)
        for (auto o : {Order::front_to_back, Order::back_to_front}) {
            RenderSettings s = base(k, Model::emission_absorption, o);
            for (const Camera& cam : cameras(density)) {
                s.skip_empty = true;
                const Image on = Renderer(density, color, s).render(cam);
                s.skip_empty = false;
                const Image off = Renderer(density, color, s).render(cam);
                EXPECT_TRUE(same_pixels(on, off)) << to_string(k) << " " << to_string(o);
            }
        }
}

// EmptySpace::empty_share_in_pairs over 4³ macrocells of 2³ cells (nodes
// 0..8 per axis): a node inside macrocell (0, 0, 0) leaves its 7 neighbours
// of the group empty (7/8); one more at the far corner, in macrocell
// (3, 3, 3), adds a group of the same share; a node on the corner that 8
// macrocells share fills the first group (7/16).
TEST(EmptySpace, EmptySharesInPairsCountTheGroupsWithANonEmptyMacrocell) {
    Volume v({9, 9, 9}, DType::f32);
    EXPECT_EQ(EmptySpace::for_zeros(v, 1, 1).empty_share_in_pairs(), 0.0);  // nothing non-empty
    v.set_value(1, 1, 1, 1.0);
    EXPECT_EQ(EmptySpace::for_zeros(v, 1, 1).empty_share_in_pairs(), 7.0 / 8);
    v.set_value(8, 8, 8, 1.0);
    EXPECT_EQ(EmptySpace::for_zeros(v, 1, 1).empty_share_in_pairs(), 14.0 / 16);
    v.set_value(2, 2, 2, 1.0);
    EXPECT_EQ(EmptySpace::for_zeros(v, 1, 1).empty_share_in_pairs(), 7.0 / 16);
    // an odd count of macrocells per axis: the last group is clipped (3 × 4 × 4 macrocells)
    Volume w({7, 9, 9}, DType::f32);
    w.set_value(5, 1, 1, 1.0);  // macrocell (2, 0, 0): its group holds 1 × 2 × 2
    EXPECT_EQ(EmptySpace::for_zeros(w, 1, 1).empty_share_in_pairs(), 3.0 / 4);
}

// EmptySpace::coarser: where every empty range lies below E, macrocells of
// twice the edge made from 8 of them are the ones for_scalar classifies,
// flag for flag, with the same pixel bounds: three models, a NaN node,
// and 2³ macrocells whose count along each axis is odd (clipped groups).
TEST(EmptySpace, CoarserMacrocellsAreTheirOwnClassification) {
    Volume v = make_volume(39, 31, 43, [](double x, double y, double z) {
        const double d = std::sqrt((x - 12) * (x - 12) + (y - 20) * (y - 20) + (z - 30) * (z - 30));
        return std::max(0.0, 1.0 - d / 8.0) + (x + y > 60 ? 0.5 : 0.0);
    });
    v.set_value(30, 5, 8, std::numeric_limits<double>::quiet_NaN());
    const Classifier c(blob_tf(), v.smallest_spacing());
    for (Model m : kModels) {
        const EmptySpace fine = EmptySpace::for_scalar(v, c, m, 1, 2);
        ASSERT_TRUE(fine.joins_empty()) << to_string(m);
        ASSERT_EQ(fine.dims(), (std::array<std::int64_t, 3>{19, 15, 21}));
        const EmptySpace made = fine.coarser(), direct = EmptySpace::for_scalar(v, c, m, 2, 2);
        ASSERT_EQ(made.dims(), direct.dims());
        EXPECT_EQ(made.edge(), 4);
        int empty = 0, differ = 0;
        const auto& d = direct.dims();
        for (std::int64_t z = 0; z < d[2]; ++z)
            for (std::int64_t y = 0; y < d[1]; ++y)
                for (std::int64_t x = 0; x < d[0]; ++x) {
                    empty += direct.empty({x, y, z}) ? 1 : 0;
                    differ += made.empty({x, y, z}) != direct.empty({x, y, z}) ? 1 : 0;
                }
        EXPECT_EQ(differ, 0) << to_string(m);
        EXPECT_GT(empty, 100) << to_string(m);
        EXPECT_LT(empty, d[0] * d[1] * d[2] - 100) << to_string(m);
        EXPECT_EQ(made.any(), direct.any());
        EXPECT_EQ(made.joins_empty(), direct.joins_empty());
        for (const Camera& cam : cameras(v)) {
            const PixelBounds a = made.pixel_bounds(cam, 40, 30, v.axes(), v.origin(), 2);
            const PixelBounds b = direct.pixel_bounds(cam, 40, 30, v.axes(), v.origin(), 2);
            EXPECT_TRUE(a.lo == b.lo && a.hi == b.hi) << to_string(m);
        }
    }
}

// The renderer skips by 2³ macrocells up to RenderSettings::
// fine_macrocells_max of them (the blobs' 36×28×44 cells: 18×14×22 = 5544)
// where they skip a quarter of what 4³ ones would evaluate (the blobs:
// more), by 4³ otherwise; the projections (average, mip, minip) keep 4³
// for their macrocells of zeros.
TEST(EmptySpace, RendererTakesFineMacrocellsWhereTheyPay) {
    const Volume v = blobs();
    const Classifier c(blob_tf(), v.smallest_spacing());
    EXPECT_GE(EmptySpace::for_scalar(v, c, Model::emission_absorption, 1, 1).empty_share_in_pairs(), 0.25);
    RenderSettings s = base(IntegratorKind::alpha, Model::emission_absorption, Order::front_to_back);
    EXPECT_EQ(Renderer(v, blob_tf(), s).macrocell_cells(), 2);  // the default limit
    s.fine_macrocells_max = 18 * 14 * 22;
    EXPECT_EQ(Renderer(v, blob_tf(), s).macrocell_cells(), 2);
    s.fine_macrocells_max -= 1;
    EXPECT_EQ(Renderer(v, blob_tf(), s).macrocell_cells(), 4);
    s.fine_macrocells_max = RenderSettings{}.fine_macrocells_max;
    s.model = Model::isosurface;
    s.isosurfaces = {{0.5, {1, 1, 1}, 1.0}};
    EXPECT_EQ(Renderer(v, blob_tf(), s).macrocell_cells(), 2);
    s.model = Model::average;
    EXPECT_EQ(Renderer(v, blob_tf(), s).macrocell_cells(), 4);
    s.model = Model::mip;
    EXPECT_EQ(Renderer(v, blob_tf(), s).macrocell_cells(), 4);
    s.model = Model::minip;
    EXPECT_EQ(Renderer(v, blob_tf(), s).macrocell_cells(), 4);
    s.model = Model::emission_absorption;
    s.skip_empty = false;
    EXPECT_EQ(Renderer(v, blob_tf(), s).macrocell_cells(), 0);
    // visible below x = 20, empty beyond: 4³ macrocells skip as much as 2³
    const Volume half = make_volume(37, 29, 45, [](double x, double, double) { return x < 20 ? 0.5 : 0.0; });
    const Classifier ch(blob_tf(), half.smallest_spacing());
    const EmptySpace fine = EmptySpace::for_scalar(half, ch, Model::emission_absorption, 1, 1);
    ASSERT_TRUE(fine.any());
    EXPECT_LT(fine.empty_share_in_pairs(), 0.25);
    s.skip_empty = true;
    EXPECT_EQ(Renderer(half, blob_tf(), s).macrocell_cells(), 4);
}

// A small blob in a large box: far from it, a ray crosses a whole box of
// empty macrocells (the distance to the blob) in one step; images stay
// bit-identical.
TEST(EmptySpace, BoxesAheadSkipLargeRegionsExactly) {
    Volume v = make_volume(83, 71, 97, [](double x, double y, double z) {
        const double d = std::sqrt((x - 60) * (x - 60) + (y - 50) * (y - 50) + (z - 70) * (z - 70));
        return std::max(0.0, 1.0 - d / 9.0);
    });
    v.set_spacing({1.0, 1.2, 0.9});
    const Classifier c(blob_tf(), v.smallest_spacing());
    for (int shift : {2, 3}) {
        const EmptySpace es = EmptySpace::for_scalar(v, c, Model::emission_absorption, shift, 1);
        EXPECT_GE(es.distance_ahead(es.macrocell({1, 1, 1}), 0), 4) << shift;  // towards the blob
        EXPECT_FALSE(es.empty(es.macrocell({60, 50, 70}))) << shift;
        const auto& d = es.dims();
        std::vector<std::array<std::int64_t, 3>> full, empty;
        for (std::int64_t z = 0; z < d[2]; ++z)
            for (std::int64_t y = 0; y < d[1]; ++y)
                for (std::int64_t x = 0; x < d[0]; ++x)
                    (es.empty({x, y, z}) ? empty : full).push_back({x, y, z});
        ASSERT_FALSE(full.empty());
        ASSERT_FALSE(empty.empty());
        // Ahead in each octant: the nearest macrocell of the other kind in
        // the octant's cone, by the largest per-axis step to it (the cap
        // where there is none).
        int wrong = 0, deep_empty = 0, deep_full = 0;
        for (int o = 0; o < 8; ++o)
            for (const auto* kind : {&empty, &full})
                for (const auto& m : *kind) {
                    int best = EmptySpace::kMaxDistance;
                    for (const auto& f : kind == &empty ? full : empty) {
                        std::int64_t reach = 0;
                        bool ahead = true;
                        for (int a = 0; a < 3; ++a) {
                            const std::int64_t step = ((o >> a) & 1) != 0 ? m[a] - f[a] : f[a] - m[a];
                            ahead = ahead && step >= 0;
                            reach = std::max(reach, step);
                        }
                        if (ahead) best = std::min<int>(best, static_cast<int>(reach));
                    }
                    wrong += es.distance_ahead(m, o) != best ? 1 : 0;
                    (kind == &empty ? deep_empty : deep_full) += best >= 3 ? 1 : 0;
                }
        EXPECT_EQ(wrong, 0) << shift;
        EXPECT_GT(deep_empty, 0) << shift;
        if (shift == 2) {
            EXPECT_GT(deep_full, 0);  // the blob's inside is a box of non-empty macrocells
        }
    }
    for (auto k : kSkipping)
        for (auto o : {Order::front_to_back, Order::back_to_front})
            EXPECT_EQ(compare_scalar(v, blob_tf(), base(k, Model::emission_absorption, o)), 0)
                << to_string(k) << " " << to_string(o);
}

// EmptySpace::along: the box ahead of a macrocell, kept as wide across and
// made longer along one axis, holds only macrocells of that one's kind, and
// it is longer than the box ahead somewhere.
TEST(EmptySpace, LongerBoxesAlongAnAxisHoldOneKind) {
    Volume v = make_volume(83, 71, 97, [](double x, double y, double z) {
        const double a = std::sqrt((x - 60) * (x - 60) + (y - 50) * (y - 50) + (z - 70) * (z - 70));
        const double b = std::sqrt((x - 15) * (x - 15) + (y - 20) * (y - 20) + (z - 25) * (z - 25));
        return std::max({0.0, 1.0 - a / 9.0, 1.0 - b / 6.0});
    });
    const Classifier c(blob_tf(), v.smallest_spacing());
    const EmptySpace es = EmptySpace::for_scalar(v, c, Model::emission_absorption, 2, 1);
    const auto& d = es.dims();
    const auto n = static_cast<std::size_t>(d[0] * d[1] * d[2]);
    int wrong = 0, shorter = 0, longer = 0;
    for (int o = 0; o < 8; ++o) {
        const std::uint8_t* along = es.along(o, 7);
        for (std::int64_t z = 0; z < d[2]; ++z)
            for (std::int64_t y = 0; y < d[1]; ++y)
                for (std::int64_t x = 0; x < d[0]; ++x) {
                    const std::array<std::int64_t, 3> m{x, y, z};
                    const int D = es.distance_ahead(m, o);
                    for (int a = 0; a < 3; ++a) {
                        const int len = along[static_cast<std::size_t>(a) * n + es.index(m)];
                        shorter += len < D ? 1 : 0;
                        longer += len > D ? 1 : 0;
                        std::array<std::int64_t, 3> lo{}, hi{};
                        for (int b = 0; b < 3; ++b) {
                            const std::int64_t r = (b == a ? len : D) - 1;
                            const bool down = ((o >> b) & 1) != 0;
                            lo[b] = down ? std::max<std::int64_t>(m[b] - r, 0) : m[b];
                            hi[b] = down ? m[b] : std::min(m[b] + r, d[b] - 1);
                        }
                        for (std::int64_t k = lo[2]; k <= hi[2]; ++k)
                            for (std::int64_t j = lo[1]; j <= hi[1]; ++j)
                                for (std::int64_t i = lo[0]; i <= hi[0]; ++i)
                                    wrong += es.empty({i, j, k}) != es.empty(m) ? 1 : 0;
                    }
                }
    }
    EXPECT_EQ(wrong, 0);
    EXPECT_EQ(shorter, 0);
    EXPECT_GT(longer, 0);
}

// Empty stretches longer than the distance cap (kMaxDistance macrocells):
// the boxes ahead stop at the cap, the walks go on from there, and images
// (packets and ray by ray) stay bit-identical to rendering without skipping.
TEST(EmptySpace, EmptyStretchesBeyondTheDistanceCapStayExact) {
    // two blobs at the ends: rays from either side walk from one across
    // the empty middle (260 macrocells) to the other
    const Volume v = make_volume(560, 24, 20, [](double x, double y, double z) {
        auto blob = [&](double cx) {
            return std::max(
                0.0, 1.0 - std::sqrt((x - cx) * (x - cx) + (y - 12) * (y - 12) + (z - 10) * (z - 10)) / 8.0);
        };
        return 0.4 * blob(12) + 0.4 * blob(548);  // faint: rays reach the far one
    });
    const Classifier c(blob_tf(), v.smallest_spacing());
    const EmptySpace es = EmptySpace::for_scalar(v, c, Model::emission_absorption, 1, 1);
    ASSERT_GT(es.dims()[0], EmptySpace::kMaxDistance + 8);
    const auto far = es.macrocell({536, 12, 10});
    EXPECT_EQ(es.distance_ahead(far, 1), EmptySpace::kMaxDistance);  // down x: capped
    EXPECT_EQ(es.along(1, 1)[es.index(far)], EmptySpace::kMaxDistance);
    const Bounds b = volume_bounds(v);
    std::vector<Camera> cams;  // along x both ways (orthographic: every ray meets both), and oblique
    for (const double az : {0.0, 180.0, 1.0}) {
        Camera cam = Camera::orbit(az, az == 1.0 ? 0.5 : 0.0, 1.3, b.center, b.radius);
        cam.projection = Projection::orthographic;
        cam.height = 26;
        cams.push_back(cam);
    }
    int bad = 0, checked = 0;
    for (auto k : kSkipping)
        for (bool packets : {true, false}) {
            RenderSettings s = base(k, Model::emission_absorption, Order::front_to_back);
            s.packets = packets;
            s.step = 0.9;
            for (const Camera& cam : cams) {
                s.skip_empty = false;
                const Image off = Renderer(v, blob_tf(), s).render(cam);
                s.skip_empty = true;
                const Renderer on(v, blob_tf(), s);
                ASSERT_EQ(on.macrocell_cells(), 2);
                bad += same_pixels(on.render(cam), off) ? 0 : 1;
                ++checked;
            }
        }
    EXPECT_EQ(bad, 0) << checked;
}

// The pre-integrated shortcut for ramps where the medium is zero returns the
// very bits the full evaluation gives, for every model and both variants.
TEST(EmptySpace, ZeroRampShortcutMatchesTheFullIntegralBitForBit) {
    int shortcuts = 0;
    for (bool associated : {false, true}) {
        const Classifier tf(blob_tf(associated), 1.0);
        auto check = [&]<Model M>() {
            for (int a = -3; a <= 14; ++a)
                for (int b = -3; b <= 14; ++b)
                    for (bool full : {true, false}) {
                        const double vf = a * 0.05, vb = b * 0.05 + 0.013;
                        RampIntegral<M> acc(0.7, full);
                        for_each_ramp_piece(tf, vf, vb, [&](const RampPiece& p) { acc.add(p); });
                        // without self-attenuation: the integral functions' difference
                        const bool integrals = !full && preint::steep_ramp(tf.integrals(), vf, vb);
                        const Segment want = integrals
                                                 ? preint::integral_segment<M>(tf.integrals(), vf, vb, 0.7)
                                                 : acc.result(),
                                      got = preintegrate_scalar<M>(tf, vf, vb, 0.7, full);
                        EXPECT_EQ(std::memcmp(&want, &got, sizeof(Segment)), 0) << vf << " " << vb;
                        if (medium_zero_on(tf, M, std::min(vf, vb), std::max(vf, vb))) ++shortcuts;
                    }
        };
        check.template operator()<Model::emission_absorption>();
        check.template operator()<Model::absorption>();
        check.template operator()<Model::emission>();
    }
    EXPECT_GT(shortcuts, 100);
}

// The walk itself, sample by sample: every sample of a skipped run has its
// computed position in an empty macrocell, on oblique rays, rays along and
// nearly along macrocell faces (where rounding decides the side) and rays
// starting on faces, in both directions and on both sample grids. (Ending
// an empty run 1e−14 of a step before the estimated box exit, without the
// check on its last sample, passes the image tests but fails this one.)
TEST(EmptySpace, SkippedRunsHoldOnlySamplesInEmptyMacrocells) {
    const Volume v = blobs();
    const Classifier c(blob_tf(), 1.0);
    const EmptySpace es = EmptySpace::for_scalar(v, c, Model::emission_absorption, 2, 1);
    std::mt19937 rng(7);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    std::vector<std::pair<Vec3, Vec3>> rays;  // origin (index space), direction
    const auto& dims = v.dims();
    for (int r = 0; r < 300; ++r) {
        const int a = r % 3;
        // a point inside the lattice the ray passes through
        Vec3 q{(u(rng) + 1) * 0.5 * static_cast<double>(dims[0] - 1),
               (u(rng) + 1) * 0.5 * static_cast<double>(dims[1] - 1),
               (u(rng) + 1) * 0.5 * static_cast<double>(dims[2] - 1)};
        Vec3 d{u(rng), u(rng), u(rng)};
        const int kind = r % 5;
        if (kind != 0) q[a] = 4.0 * std::floor(q[a] / 4.0);     // on a macrocell face
        if (kind == 1) d[a] = 0.0;                              // along it
        if (kind == 2) d[a] = std::pow(10.0, -3.0 - (r % 13));  // nearly along it
        if (kind == 4) {                                        // along a line of faces
            d = {0, 0, 0};
            d[a] = r % 2 == 0 ? 1.0 : -1.0;
            q[(a + 1) % 3] = 4.0 * std::floor(q[(a + 1) % 3] / 4.0);
        }
        d = d * (1.0 / length(d));
        rays.push_back({q - d * 80.0, d});
    }
    std::int64_t skipped = 0, checked_rays = 0;
    for (const auto& [p0, dp] : rays) {
        RaySpan span;
        if (!intersect_box(p0, dp, v.dims(), span)) continue;
        ++checked_rays;
        for (double h : {0.37, 1.0}) {
            const std::int64_t n = segment_count(span.length(), h);
            const double delta = span.length() / static_cast<double>(n);
            for (const SampleGrid g : {SampleGrid{&span, delta, 0.5, 1}, SampleGrid{&span, delta, 0.0, 0}}) {
                const RunFinder runs(es, g);
                const std::int64_t lo = g.first, hi = n;
                for (int dir : {+1, -1})
                    for (std::int64_t i = dir > 0 ? lo : hi; i >= lo && i <= hi;) {
                        const auto run = runs.run(i, dir, dir > 0 ? hi : lo);
                        ASSERT_TRUE(dir > 0 ? run.last >= i && run.last <= hi
                                            : run.last <= i && run.last >= lo);
                        if (run.empty)
                            for (std::int64_t k = i; k != run.last + dir; k += dir) {
                                ASSERT_TRUE(es.empty(es.macrocell(g.at(k))))
                                    << "sample " << k << " of a skipped run " << i << ".." << run.last;
                                ++skipped;
                            }
                        i = run.last + dir;
                    }
            }
        }
    }
    EXPECT_EQ(checked_rays, 300);
    EXPECT_GT(skipped, 100000);
}

// Pre-integrated segments between two empty macrocells of different boxes
// are skipped only where every empty range lies in one zero interval
// (EmptySpace::joins_empty). Two zero bands, v ≤ 0.2 and v ≥ 0.6, with σ > 0
// between, on slabs of 0.1 and 0.9 with a sharp step: segments longer than a
// macrocell join a 0.1 end to a 0.9 end across the non-empty step, and
// their ramps cross the band where σ > 0.
TEST(EmptySpace, SegmentsJoinEmptyMacrocellsOnlyWithinOneZeroInterval) {
    const Volume slabs = make_volume(41, 23, 19, [](double x, double y, double) {
        return std::fmod(x + 0.3 * y, 14.0) < 7.0 ? 0.1 : 0.9;
    });
    TransferFunction two;
    two.alpha_kind = TransferFunction::Alpha::extinction;
    two.alpha_points = {{0.0, 0.0}, {0.2, 0.0}, {0.3, 1.5}, {0.5, 1.5}, {0.6, 0.0}, {1.0, 0.0}};
    two.color_points = {{0.0, {0.9, 0.4, 0.1}}, {1.0, {0.1, 0.5, 0.9}}};
    const Classifier c_two(two, 1.0), c_blob(blob_tf(), 1.0);
    const EmptySpace es_two = EmptySpace::for_scalar(slabs, c_two, Model::emission_absorption, 2, 1);
    ASSERT_TRUE(es_two.any());
    EXPECT_FALSE(es_two.joins_empty());  // empty ranges in both bands
    EXPECT_TRUE(EmptySpace::for_scalar(slabs, c_blob, Model::emission_absorption, 2, 1).joins_empty());
    EXPECT_TRUE(EmptySpace::for_zeros(slabs, 2, 1).joins_empty());
    int compared = 0;
    for (IntegratorKind k : {IntegratorKind::preintegrated, IntegratorKind::preintegrated_simple})
        for (Order o : {Order::front_to_back, Order::back_to_front})
            for (double step : {5.3, 9.1}) {
                RenderSettings s = base(k, Model::emission_absorption, o);
                s.step = step;
                EXPECT_EQ(compare_scalar(slabs, two, s), 0) << to_string(k) << " step " << step;
                ++compared;
            }
    EXPECT_EQ(compared, 8);
}

namespace {
void check_pixel_bounds(const Volume& v, bool slab) {
    const Classifier c(blob_tf(), v.smallest_spacing());
    const EmptySpace es = EmptySpace::for_scalar(v, c, Model::emission_absorption, 2, 2);
    const Mat3 to_index = v.axes().inverse();
    std::mt19937 rng(11);
    std::uniform_real_distribution<double> jiggle(-0.9 * PixelBounds::kMargin, 0.9 * PixelBounds::kMargin);
    const int w = 48, h = 36;
    for (const Camera& cam : cameras(v)) {
        const PixelBounds pb = es.pixel_bounds(cam, w, h, v.axes(), v.origin(), 2);
        ASSERT_TRUE(pb.any());
        // each thread draws its share of the boxes, then they merge: the
        // same bounds whatever the thread count
        for (int threads : {1, 2, 3}) {  // a thread per box or two: these few boxes divide too
            const PixelBounds other = es.pixel_bounds(cam, w, h, v.axes(), v.origin(), threads, 2);
            EXPECT_TRUE(other.lo == pb.lo && other.hi == pb.hi) << threads << " threads";
        }
        int none = 0, inside = 0, near_points = 0, wrong = 0;
        for (int y = 0; y < h; ++y)
            for (int x = 0; x < w; ++x) {
                double lo = 0, hi = 0;
                pb.at(x, y, lo, hi);
                const Ray ray = cam.generate(x, y, w, h);
                RaySpan span;
                if (!intersect_box(to_index * (ray.origin - v.origin()), to_index * ray.dir, v.dims(), span))
                    continue;
                none += lo > hi ? 1 : 0;
                inside += lo > span.t_near + 1.0 ? 1 : 0;
                for (int k = 0; k <= 600; ++k) {
                    const double t = span.t_near + span.length() * k / 600.0;
                    Vec3 p = span.at(t);
                    for (int a = 0; a < 3; ++a) p[a] += jiggle(rng);
                    if (es.empty(es.macrocell(p))) continue;
                    ++near_points;
                    wrong += t >= lo && t <= hi ? 0 : 1;
                }
            }
        EXPECT_EQ(wrong, 0);
        EXPECT_GT(near_points, 1000);
        if (!slab) {
            EXPECT_GT(none, 50);
        }
        EXPECT_GT(inside, 50);
    }
    // No bounds when the lattice is not wholly in front of the camera, or
    // the camera's axes are not orthonormal.
    const Bounds b = volume_bounds(v);
    EXPECT_FALSE(
        es.pixel_bounds(Camera::orbit(20, 10, 0.3, b.center, b.radius), w, h, v.axes(), v.origin(), 1).any());
    Camera skew = cameras(v)[2];
    skew.up = normalize(skew.up + skew.right * 1e-4);
    EXPECT_FALSE(es.pixel_bounds(skew, w, h, v.axes(), v.origin(), 1).any());
}
}  // namespace

// A frame's PixelBounds: the same for 1, 2 and 3 threads; every point of a
// pixel's ray within kMargin of a non-empty macrocell has its t in the
// pixel's [lo, hi]; rays that miss the
// blobs get none (lo > hi), and the rays that meet them start their bounds
// inside the volume, not at its box. Blobs, and blobs with a slab through
// the whole box (non-empty macrocells that rays enter only from the grid's
// edge).
TEST(EmptySpace, PixelBoundsHoldEveryPointNearNonEmptyMacrocells) {
    check_pixel_bounds(blobs(), false);
    Volume slab = blobs();
    for (std::int64_t k = 20; k < 30; ++k)
        for (std::int64_t j = 0; j < 29; ++j)
            for (std::int64_t i = 0; i < 37; ++i) slab.set_value(i, j, k, 0.7);
    check_pixel_bounds(slab, true);
}

// With the bounds (Renderer::render) and without (Renderer::trace, ray by
// ray): the same bits, for each integrator that uses them, a camera inside
// the volume included.
TEST(EmptySpace, RenderWithPixelBoundsMatchesTracingEachRay) {
    const Volume v = blobs();
    const Bounds b = volume_bounds(v);
    std::vector<Camera> cams = cameras(v);
    cams.push_back(Camera::orbit(20, 10, 0.3, b.center, b.radius));
    for (auto k : kSkipping)
        for (auto o : {Order::front_to_back, Order::back_to_front}) {
            RenderSettings s = base(k, Model::emission_absorption, o);
            s.width = 24;
            s.height = 20;
            const Renderer r(v, blob_tf(), s);
            for (const Camera& cam : cams) {
                const Image img = r.render(cam);
                int differ = 0;
                for (int y = 0; y < s.height; ++y)
                    for (int x = 0; x < s.width; ++x) {
                        const RayResult t = r.trace(cam.generate(x, y, s.width, s.height));
                        const float* p = img.pixel(x, y);
                        for (int ch = 0; ch < 3; ++ch)
                            differ += p[ch] != static_cast<float>(t.radiance[ch]) ? 1 : 0;
                        differ += p[3] != static_cast<float>(t.alpha) ? 1 : 0;
                    }
                EXPECT_EQ(differ, 0) << to_string(k) << " " << to_string(o);
            }
        }
}

// Threads that need an octant's tables at once build them together (each
// takes planes of macrocells; ahead()'s planes wait on the rows ahead of
// them): the tables equal those one thread builds alone, whatever axes of
// along() each thread asks for.
TEST(EmptySpace, ThreadsThatNeedATableAtOnceBuildItTogether) {
    Volume v = make_volume(97, 83, 121, [](double x, double y, double z) {
        const double a = std::sqrt((x - 60) * (x - 60) + (y - 50) * (y - 50) + (z - 70) * (z - 70));
        const double b = std::sqrt((x - 15) * (x - 15) + (y - 20) * (y - 20) + (z - 25) * (z - 25));
        return std::max({0.0, 1.0 - a / 21.0, 1.0 - b / 9.0, 0.6 * std::sin(0.35 * x) * std::sin(0.3 * z)});
    });
    const Classifier c(blob_tf(), v.smallest_spacing());
    const EmptySpace alone = EmptySpace::for_scalar(v, c, Model::emission_absorption, 1, 1);
    const auto n = static_cast<std::size_t>(alone.dims()[0] * alone.dims()[1] * alone.dims()[2]);
    ASSERT_GT(alone.dims()[2], 32);
    for (int round = 0; round < 4; ++round) {
        const EmptySpace shared = EmptySpace::for_scalar(v, c, Model::emission_absorption, 1, 1);
        constexpr int kThreads = 4;
        std::latch start(kThreads);
        std::vector<std::thread> pool;
        for (int t = 0; t < kThreads; ++t)
            pool.emplace_back([&, t] {
                start.arrive_and_wait();
                for (int k = 0; k < 8; ++k) {
                    const int o = (k + round) % 8;  // the same octant at once
                    if (t == 0) static_cast<void>(shared.ahead(o));
                    static_cast<void>(shared.along(o, t == 1 ? 1u : t == 2 ? 6u : 7u));
                }
            });
        for (auto& th : pool) th.join();
        int wrong = 0;
        for (int o = 0; o < 8; ++o) {
            wrong += std::memcmp(shared.ahead(o), alone.ahead(o), n) != 0 ? 1 : 0;
            wrong += std::memcmp(shared.along(o, 7), alone.along(o, 7), 3 * n) != 0 ? 1 : 0;
        }
        EXPECT_EQ(wrong, 0) << "round " << round;
    }
}

// A releasing Use (a frame) frees the octants' tables nothing read since the
// previous one began, keeps those read, frees nothing while another Use is
// in flight, and a freed table comes back with the same bytes.
TEST(EmptySpace, FramesFreeTheOctantTablesTheLastFrameDidNotRead) {
    Volume v({24, 20, 16}, DType::f32, 1);
    for (std::int64_t z = 0; z < 16; ++z)
        for (std::int64_t y = 0; y < 20; ++y)
            for (std::int64_t x = 0; x < 24; ++x)
                v.set_value(x, y, z, (x - 12) * (x - 12) + (y - 9) * (y - 9) < 30 && z > 5 ? 1.0 : 0.0);
    const EmptySpace es = EmptySpace::for_zeros(v, 2, 1);
    ASSERT_TRUE(es.any());
    const std::size_t n = static_cast<std::size_t>(es.dims()[0] * es.dims()[1] * es.dims()[2]);
    const std::vector<std::uint8_t> first(es.ahead(5), es.ahead(5) + n);
    static_cast<void>(es.along(2, 1u));
    EXPECT_EQ(es.table_bytes(), 3 * n);         // two octants' ahead, one along axis
    { const EmptySpace::Use frame(es, true); }  // both read before it: kept
    EXPECT_EQ(es.table_bytes(), 3 * n);
    {
        const EmptySpace::Use frame(es, true);  // the last frame read nothing: all freed
        EXPECT_EQ(es.table_bytes(), 0u);
        EXPECT_EQ(std::vector<std::uint8_t>(es.ahead(5), es.ahead(5) + n), first);
        const EmptySpace::Use other(es, true);  // in flight beside `frame`: frees nothing
        EXPECT_EQ(es.table_bytes(), n);
    }
    { const EmptySpace::Use frame(es, true); }  // octant 5 was read: kept
    EXPECT_EQ(es.table_bytes(), n);
}
