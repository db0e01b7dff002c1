// Bricked storage (src/volume/bricks.h) and the renderer that samples from
// it: every cell's corners read the same nodes, the SIMD gathers give the
// same values, and a renderer that takes its volume over renders the same
// bits from bricks.
#include <cstdint>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "fathom/render.h"

#include "integrate/simd_classify.h"
#include "simd_check.h"
#include "synthetic.h"
#include "volume/bricks.h"
#include "volume/sampler.h"

using namespace fathom;

namespace {

// Dimensions that end inside a brick on every axis, one exactly on a
// brick's edge (65 nodes: 64 cells, two whole bricks along y).
constexpr std::array<std::int64_t, 3> kDims{70, 65, 37};
// For renderers, which brick only where the bricks take at most a quarter
// more bytes: 61 × 62 × 30 cells in 2 × 2 × 1 bricks (1.19×), each axis
// ending inside one.
constexpr std::array<std::int64_t, 3> kRenderDims{62, 63, 31};

Volume noise(DType type, std::array<std::int64_t, 3> dims = kDims, std::uint32_t seed = 5) {
    Volume v(dims, type);
    std::mt19937 rng(seed);
    std::uniform_int_distribution<int> value(type == DType::i8 || type == DType::i16 ? -120 : 0, 250);
    for (std::int64_t k = 0; k < dims[2]; ++k)
        for (std::int64_t j = 0; j < dims[1]; ++j)
            for (std::int64_t i = 0; i < dims[0]; ++i) v.set_value(i, j, k, value(rng));
    v.set_spacing({1.0, 0.8, 1.2});
    return v;
}

template <class T>
T at(const Bricks& b, std::int64_t index) {
    T x;
    std::memcpy(&x, b.bytes() + index * static_cast<std::int64_t>(sizeof(T)), sizeof(T));
    return x;
}

bool same(const Image& a, const Image& b) {
    return a.rgba.size() == b.rgba.size() &&
           std::memcmp(a.rgba.data(), b.rgba.data(), sizeof(float) * a.rgba.size()) == 0;
}

constexpr DType kPaired[] = {DType::u8, DType::i8, DType::u16, DType::i16, DType::f32};

/// The corners of v's cells, read through b.cell_index, that differ from v's nodes.
std::int64_t wrong_corners(const Bricks& b, const Volume& v) {
    const auto& d = v.dims();
    std::int64_t wrong = 0;
    visit_dtype(v.dtype(), [&]<class T>(T*) {
        const T* lin = v.data<T>();
        for (std::int64_t k = 0; k + 1 < d[2]; ++k)
            for (std::int64_t j = 0; j + 1 < d[1]; ++j)
                for (std::int64_t i = 0; i + 1 < d[0]; ++i) {
                    const std::int64_t c = b.cell_index(i, j, k);
                    for (int n = 0; n < 8; ++n) {
                        const int dx = n & 1, dy = (n >> 1) & 1, dz = n >> 2;
                        const T want = lin[i + dx + d[0] * (j + dy + d[1] * (k + dz))];
                        const T got = at<T>(b, c + dx + Bricks::kNodes * (dy + Bricks::kNodes * dz));
                        wrong += std::memcmp(&want, &got, sizeof(T)) != 0 ? 1 : 0;
                    }
                }
    });
    return wrong;
}

/// SIMD interpolation from b against GridSampler on v along `rays` random
/// rays, every third from the far corner (the last cells of the last
/// bricks); the samples compared, or −1 after a failure.
int simd_matches(const Bricks& b, const Volume& v, int rays, std::mt19937& rng) {
    const auto& d = v.dims();
    simd::BatchSource src{b.bytes(), v.dtype(), d[0], d[1], d[2], nullptr, nullptr};
    src.bricks_x = b.bricks_x();
    src.bricks_y = b.bricks_y();
    src.bricks_z = b.bricks_z();
    auto around = [](std::int64_t n) { return std::uniform_real_distribution<double>(-1.0, n + 1.0); };
    auto px = around(d[0]), py = around(d[1]), pz = around(d[2]);
    std::uniform_real_distribution<double> dir(-3.0, 3.0);
    const double magnitude = test::largest_magnitude(v);
    const Vec3 far{d[0] - 1.0, d[1] - 1.0, d[2] - 1.0};
    int compared = 0;
    for (int r = 0; r < rays; ++r) {
        simd::RayGrid g;
        g.p0 = r % 3 == 0 ? far : Vec3{px(rng), py(rng), pz(rng)};
        g.dp = {dir(rng), dir(rng), dir(rng)};
        g.delta = 0.9;
        g.offset = 0.5;
        g.first = 0;
        const int n = test::batch_matches_sampler(
            src, g, v, magnitude, std::string(dtype_name(v.dtype())) + " ray " + std::to_string(r));
        if (n < 0) return -1;
        compared += n;
    }
    return compared;
}

}  // namespace

TEST(Bricks, EveryCellsCornersReadItsNodes) {
    for (DType type : kPaired) {
        Volume v = noise(type);
        Bricks built(v, false, 2);
        const Bricks b(std::move(built));  // a moved one keeps its layout
        // 69 × 64 × 36 cells: 3 × 2 × 2 bricks of 33³ nodes, the last slab's
        // 5 planes of 33² nodes (its 4 planes of cells)
        EXPECT_EQ(b.bricks_x(), 3);
        EXPECT_EQ(b.bricks_y(), 2);
        EXPECT_EQ(b.bricks_z(), 2);
        EXPECT_EQ(b.last_planes(), 5);
        EXPECT_EQ(b.size_bytes(), (6u * 33 * 33 * 33 + 6u * 33 * 33 * 5) * dtype_size(type));
        EXPECT_EQ(Bricks::bytes_for(v), b.size_bytes());
        EXPECT_EQ(wrong_corners(b, v), 0) << dtype_name(type);
    }
}

// The last slab along z holds the lattice's planes only, however many: one
// plane of cells (2 nodes), a slab's worth (33: whole bricks), one past it.
TEST(Bricks, TheLastSlabHoldsTheLatticesPlanes) {
    std::mt19937 rng(23);
    for (const std::int64_t nz : {2, 3, 33, 34, 66})
        for (DType type : {DType::u8, DType::i16, DType::f32}) {
            const std::array<std::int64_t, 3> dims{36, 34, nz};  // 35 × 33 cells: 2 × 2 bricks a slab
            Volume v = noise(type, dims, 11);
            const Bricks b(v, false, 2);
            const std::int64_t slabs = (nz - 2) / 32 + 1, planes = nz - (slabs - 1) * 32;
            const std::string what = std::string(dtype_name(type)) + " nz " + std::to_string(nz);
            EXPECT_EQ(b.bricks_z(), slabs) << what;
            EXPECT_EQ(b.last_planes(), planes) << what;
            EXPECT_EQ(b.size_bytes(),
                      static_cast<std::size_t>(4 * ((slabs - 1) * 33 * 33 * 33 + 33 * 33 * planes)) *
                          dtype_size(type))
                << what;
            EXPECT_EQ(Bricks::bytes_for(v), b.size_bytes()) << what;
            EXPECT_EQ(wrong_corners(b, v), 0) << what;
            ASSERT_GT(simd_matches(b, v, 30, rng), 0) << what;
        }
}

// With release the source's pages go back as the bricks fill: the bricks
// are the same, and the source reads zeros where its pages went back.
TEST(Bricks, HandingTheSourceBackKeepsTheBricks) {
    const std::array<std::int64_t, 3> dims{300, 200, 70};  // 8.4 MB of uint16: whole pages to hand back
    Volume kept = noise(DType::u16, dims, 9), given = noise(DType::u16, dims, 9);
    const Bricks a(kept, false, 2), b(given, true, 2);
    ASSERT_EQ(a.size_bytes(), b.size_bytes());
    EXPECT_EQ(std::memcmp(a.bytes(), b.bytes(), a.size_bytes()), 0);
    // the whole 2 MiB pages of the first slab (planes 0..31: 3.8 MB) went
    // back; the source is 2 MiB-aligned at this size (Volume)
    const auto* g = given.data<std::uint16_t>();
    std::int64_t nonzero = 0;
    for (std::int64_t n = 0; n < (std::int64_t{2} << 20) / 2; ++n) nonzero += g[n] != 0 ? 1 : 0;
    EXPECT_EQ(nonzero, 0);
    // untouched: the kept volume still holds its samples
    EXPECT_GT(kept.value_range()[1], 0.0);
}

TEST(Bricks, SimdGathersFromBricksMatchGridSampler) {
    std::mt19937 rng(17);
    int compared = 0;
    for (DType type : kPaired) {
        Volume v = noise(type);
        const Bricks b(v, false, 1);
        const int n = simd_matches(b, v, 300, rng);
        ASSERT_GE(n, 0) << dtype_name(type);
        compared += n;
    }
    EXPECT_GE(compared, 5 * 300 * simd::kBatch);
}

TEST(Bricks, RendererThatTakesItsVolumeRendersTheSameBitsFromBricks) {
    TransferFunction tf;
    tf.alpha_kind = TransferFunction::Alpha::extinction;
    tf.alpha_points = {{60, 0.0}, {120, 0.08}, {200, 0.3}};
    tf.color_points = {{0, {0.2, 0.4, 0.9}}, {250, {1.0, 0.7, 0.3}}};
    int compared = 0;
    for (DType type : kPaired) {
        const Volume v = noise(type, kRenderDims);
        const Bounds bounds = volume_bounds(v);
        for (auto kind : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated,
                          IntegratorKind::preintegrated_simple})
            for (auto order : {Order::front_to_back, Order::back_to_front})
                for (bool skip : {true, false}) {
                    RenderSettings s;
                    s.width = 20;
                    s.height = 18;
                    s.integrator = kind;
                    s.order = order;
                    s.skip_empty = skip;
                    s.brick_min_bytes = 0;
                    const Renderer linear(v, tf, s);
                    const Renderer bricked(Volume(v), tf, s);
                    ASSERT_FALSE(linear.bricked());
                    ASSERT_TRUE(bricked.bricked()) << dtype_name(type);
                    // along each axis and off them, from outside and inside
                    for (const Camera& cam : {Camera::orbit(0, 89, 2.4, bounds.center, bounds.radius),
                                              Camera::orbit(90, 0, 2.4, bounds.center, bounds.radius),
                                              Camera::orbit(37, 21, 2.4, bounds.center, bounds.radius),
                                              Camera::orbit(200, -40, 0.4, bounds.center, bounds.radius)}) {
                        EXPECT_TRUE(same(bricked.render(cam), linear.render(cam)))
                            << dtype_name(type) << " " << to_string(kind) << " " << to_string(order)
                            << (skip ? "" : " no skipping");
                        ++compared;
                    }
                }
    }
    EXPECT_EQ(compared, 5 * 4 * 2 * 2 * 4);
}

// Bricks only where the path that reads them is the frame's: not for
// shading, the reference integrator, projections, unpaired types, small
// volumes, volumes whose bricks would take more than a quarter more bytes,
// or a volume the caller keeps.
TEST(Bricks, RendererKeepsTheLayoutWhereBricksWouldNotBeRead) {
    const TransferFunction tf = test::extinction_tf({{0, 0.0}, {250, 0.2}}, {1, 1, 1});
    RenderSettings s;
    s.brick_min_bytes = 0;
    EXPECT_TRUE(Renderer(noise(DType::u8, kRenderDims), tf, s).bricked());
    const Volume keep = noise(DType::u8, kRenderDims);
    EXPECT_FALSE(Renderer(keep, tf, s).bricked());
    EXPECT_FALSE(Renderer(noise(DType::f64, kRenderDims), tf, s).bricked());
    EXPECT_FALSE(Renderer(noise(DType::u32, kRenderDims), tf, s).bricked());
    RenderSettings shaded = s;
    shaded.shading.enabled = true;
    EXPECT_FALSE(Renderer(noise(DType::u8, kRenderDims), tf, shaded).bricked());
    RenderSettings reference = s;
    reference.integrator = IntegratorKind::reference;
    EXPECT_FALSE(Renderer(noise(DType::u8, kRenderDims), tf, reference).bricked());
    RenderSettings mip = s;
    mip.model = Model::mip;
    EXPECT_FALSE(Renderer(noise(DType::u8, kRenderDims), tf, mip).bricked());
    RenderSettings scalar = s;
    scalar.simd = false;
    EXPECT_FALSE(Renderer(noise(DType::u8, kRenderDims), tf, scalar).bricked());
    RenderSettings small = s;
    small.brick_min_bytes = 62 * 63 * 31 + 1;  // one byte more than the uint8 volume
    EXPECT_FALSE(Renderer(noise(DType::u8, kRenderDims), tf, small).bricked());
    small.brick_min_bytes -= 1;
    EXPECT_TRUE(Renderer(noise(DType::u8, kRenderDims), tf, small).bricked());
    // 69 × 64 × 36 cells in 3 × 2 × 2 bricks take 2.6× the bytes
    EXPECT_FALSE(Renderer(noise(DType::u8), tf, s).bricked());
}
