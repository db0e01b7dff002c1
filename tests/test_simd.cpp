// SIMD classification of point samples, pre-integration's end samples and
// segments (src/integrate/simd_classify.h, simd_preint.h):
// every target this CPU runs gives the scalar path's images, bit for bit
// where its lanes do not fuse multiply–adds and within simd_check.h's
// tolerances where they do.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstring>
#include <limits>
#include <random>
#include <string>
#include <utility>
#include <vector>

#include <gtest/gtest.h>

#include "fathom/render.h"

#include "integrate/exp_neg.h"
#include "integrate/point_rules.h"
#include "integrate/preintegrated.h"
#include "integrate/simd_classify.h"
#include "integrate/simd_preint.h"
#include "render/empty_space.h"
#include "render/simd_bounds.h"
#include "simd_check.h"
#include "synthetic.h"
#include "volume/sampler.h"

using namespace fathom;
using fathom::test::make_volume;

namespace {

// A smooth field with a plateau of exact knot values, stored as `type`.
Volume field(DType type) {
    const Volume f = make_volume(23, 19, 27, [](double x, double y, double z) {
        const double r = std::sqrt((x - 11) * (x - 11) + (y - 9) * (y - 9) + (z - 13) * (z - 13));
        return r < 3 ? 150.0 : std::max(0.0, 200.0 - 12.0 * r) + 3.0 * std::sin(x + 2 * y);
    });
    Volume v(f.dims(), type);
    v.set_spacing({1.0, 0.7, 1.3});
    for (std::int64_t k = 0; k < f.dims()[2]; ++k)
        for (std::int64_t j = 0; j < f.dims()[1]; ++j)
            for (std::int64_t i = 0; i < f.dims()[0]; ++i) v.set_value(i, j, k, std::round(f.value(i, j, k)));
    return v;
}

// Jumps, a knot exactly at the plateau's value, values beyond both ends.
TransferFunction tf(bool associated) {
    TransferFunction t;
    t.alpha_kind = TransferFunction::Alpha::extinction;
    t.alpha_points = {{20, 0.0}, {60, 0.05}, {100, 0.05}, {100, 0.2}, {150, 0.4}, {190, 0.1}};
    t.associated = associated;
    t.color_points = {
        {30, {0.1, 0.2, 0.9}}, {150, {1.0, 0.5, 0.2}}, {150, {0.9, 0.9, 0.9}}, {180, {1, 0, 0}}};
    return t;
}

}  // namespace

TEST(Simd, EveryTargetMatchesTheScalarPath) {
    const auto targets = simd::available_targets();
    ASSERT_FALSE(targets.empty());
    int compared = 0;
    for (DType type : {DType::u8, DType::u16, DType::i16, DType::f32, DType::f64}) {
        const Volume v = field(type);
        const Bounds b = volume_bounds(v);
        for (bool associated : {false, true})
            for (auto kind : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated,
                              IntegratorKind::preintegrated_simple})
                for (auto order : {Order::front_to_back, Order::back_to_front})
                    for (auto model : {Model::emission_absorption, Model::absorption, Model::emission}) {
                        RenderSettings s;
                        s.model = model;
                        s.width = s.height = 24;
                        s.integrator = kind;
                        s.order = order;
                        s.step = 0.37;
                        s.jitter = order == Order::back_to_front;
                        s.threads = 1;
                        const Camera cam = Camera::orbit(37, 21, 2.4, b.center, b.radius);
                        s.simd = false;
                        const Image scalar = Renderer(v, tf(associated), s).render(cam);
                        s.simd = true;
                        // without skipping, the zero split runs over the whole ray
                        for (bool skip : {true, false}) {
                            s.skip_empty = skip;
                            for (auto t : targets) {
                                simd::force_target(t);
                                EXPECT_TRUE(
                                    test::images_agree(Renderer(v, tf(associated), s).render(cam), scalar))
                                    << simd::active_target() << " " << dtype_name(type) << " "
                                    << to_string(kind) << " " << to_string(order) << " " << to_string(s.model)
                                    << (associated ? " associated" : "") << (skip ? "" : " no skipping");
                                ++compared;
                            }
                        }
                        s.skip_empty = true;
                        simd::force_target(0);
                    }
    }
    EXPECT_GE(compared, 320);
}

// Shaded frames take the SIMD batch and its zero split too: only samples
// (and pre-integrated segments) that are not zero get a gradient and a
// shade, a vector at a time. The scalar path's pixels, depths and first
// hits (test::images_agree), under lights, gradient opacity and midpoint
// samples, on a sheared lattice too.
TEST(Simd, ShadedFramesOfEveryTargetMatchTheScalarPath) {
    const auto targets = simd::available_targets();
    int compared = 0;
    for (DType type : {DType::u8, DType::u16, DType::i16, DType::f32, DType::f64}) {
        Volume v = field(type);
        if (type == DType::i16) {  // a sheared, rotated lattice: the chain rule's matrix is not symmetric
            const double a = 0.4;
            v.set_axes(Mat3::from_columns({1.2 * std::cos(a), 1.2 * std::sin(a), 0},
                                          {-std::sin(a), std::cos(a), 0.3}, {0.1, 0, 0.9}));
        }
        const Bounds b = volume_bounds(v);
        const Camera cam = Camera::orbit(37, 21, 2.4, b.center, b.radius);
        for (bool lit : {false, true})
            for (auto kind : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated,
                              IntegratorKind::preintegrated_simple})
                for (auto order : {Order::front_to_back, Order::back_to_front})
                    for (auto model : {Model::emission_absorption, Model::absorption, Model::emission}) {
                        // lit under emission–absorption only; the others have gradient opacity
                        if (!lit && model != Model::emission_absorption) continue;
                        TransferFunction t = tf(lit);
                        RenderSettings s;
                        s.model = model;
                        s.width = s.height = 20;
                        s.integrator = kind;
                        s.order = order;
                        s.step = 0.37;
                        s.threads = 1;
                        s.shading.enabled = true;
                        s.depth_outputs = true;
                        if (lit) {  // two coloured lights, a highlight, gradient opacity, midpoints
                            s.shading.lights = {{{1, 0.5, -0.2}, {1, 0.8, 0.6}},
                                                {{-0.3, 1, 0.4}, {0.2, 0.4, 1}}};
                            s.shading.specular = 0.5;
                            s.shading.shininess = type == DType::f32 ? 12.5 : 13;  // libm's pow, squarings
                            s.sample_point = SamplePoint::mid;
                            t.gradient_opacity_points = {{0, 1}, {30, 0.2}, {60, 1}};
                        }
                        s.simd = false;
                        s.skip_empty = false;
                        const Image scalar = Renderer(v, t, s).render(cam);
                        s.simd = true;
                        for (bool skip : {true, false}) {
                            s.skip_empty = skip;
                            for (auto target : targets) {
                                simd::force_target(target);
                                const Image img = Renderer(v, t, s).render(cam);
                                EXPECT_TRUE(test::images_agree(img, scalar))
                                    << simd::active_target() << " " << dtype_name(type) << " "
                                    << to_string(kind) << " " << to_string(order) << " " << to_string(model)
                                    << (lit ? " lights" : " head light") << (skip ? "" : " no skipping");
                                ++compared;
                            }
                        }
                        simd::force_target(0);
                    }
    }
    EXPECT_GE(compared, 240);
}

TEST(Simd, DispatchesToTheBestTargetByDefault) {
    simd::force_target(0);
    const std::string best = simd::active_target();
    EXPECT_FALSE(best.empty());
    // The first target in the list Highway reports is the best one.
    const auto targets = simd::available_targets();
    ASSERT_FALSE(targets.empty());
    simd::force_target(targets.front());
    EXPECT_EQ(simd::active_target(), best);
    simd::force_target(0);
}

// The scalar below which the medium is exactly zero, per model: σ = 0 below
// 20, c = 0 below 30 (associated: q).
TEST(Simd, ZeroBelowFollowsTheModel) {
    TransferFunction t;
    t.alpha_kind = TransferFunction::Alpha::extinction;
    t.alpha_points = {{20, 0.0}, {60, 0.5}};
    t.color_points = {{30, {0, 0, 0}}, {90, {1, 1, 1}}};
    const Classifier plain(t, 1.0);
    EXPECT_EQ(zero_below(plain, Model::emission_absorption), 20.0);
    EXPECT_EQ(zero_below(plain, Model::absorption), 20.0);
    EXPECT_EQ(zero_below(plain, Model::emission), 30.0);  // g = σ·c: either factor
    EXPECT_EQ(zero_below(plain, Model::mip), -INFINITY);
    t.associated = true;
    const Classifier assoc(t, 1.0);
    EXPECT_EQ(zero_below(assoc, Model::emission_absorption), 20.0);  // both σ and q
    EXPECT_EQ(zero_below(assoc, Model::emission), 30.0);
    t.alpha_points = {{20, 0.0}};
    EXPECT_EQ(zero_below(Classifier(t, 1.0), Model::absorption), INFINITY);
    t.alpha_points = {{20, 0.1}, {60, 0.0}};
    EXPECT_EQ(zero_below(Classifier(t, 1.0), Model::absorption), -INFINITY);
}

// The end samples alone, for every target and sample type, against
// GridSampler: random values over each type's whole range (the signs of
// int16), on rays through every region of a small lattice and out of its
// far corner, where a 4-byte read of the last uint8 row would pass the end.
TEST(Simd, EndSamplesMatchGridSamplerOverEveryValue) {
    std::mt19937 rng(11);
    int compared = 0;
    for (DType type : {DType::u8, DType::i8, DType::u16, DType::i16, DType::u32, DType::f32}) {
        Volume v({5, 4, 3}, type);
        const auto [lo, hi] = visit_dtype(type, []<class T>(T*) {
            return std::pair<double, double>{std::max<double>(std::numeric_limits<T>::lowest(), -1e6),
                                             std::min<double>(std::numeric_limits<T>::max(), 1e6)};
        });
        std::uniform_real_distribution<double> value(lo, hi);
        for (std::int64_t k = 0; k < 3; ++k)
            for (std::int64_t j = 0; j < 4; ++j)
                for (std::int64_t i = 0; i < 5; ++i) v.set_value(i, j, k, std::round(value(rng)));
        // half the values below zero_below: the batch's bits of them
        const simd::BatchSource src{v.bytes(), type, 5, 4, 3, nullptr, nullptr, 0.5 * (lo + hi)};
        std::uniform_real_distribution<double> pos(-0.5, 5.5), dir(-1.0, 1.0);
        const double magnitude = test::largest_magnitude(v);
        for (int r = 0; r < 200; ++r) {
            simd::RayGrid g;
            g.p0 = r % 2 == 0 ? Vec3{pos(rng), pos(rng), pos(rng)} : Vec3{4.0, 3.0, 2.0};  // the far corner
            g.dp = {dir(rng), dir(rng), dir(rng)};
            g.t_near = 0.0;
            g.delta = 0.31;
            g.offset = 0.25;
            g.first = 0;
            const int n = test::batch_matches_sampler(
                src, g, v, magnitude, std::string(dtype_name(type)) + " ray " + std::to_string(r));
            ASSERT_GE(n, 0);
            compared += n;
        }
    }
    EXPECT_GE(compared, 6 * 200 * simd::kBatch);
}

// The skip convention of composite() over a batch's zero lanes, both ways.
TEST(Simd, SplitZeroCountsRunsOfZeroLanes) {
    const std::uint32_t z = 0b0000'1111'0000'0110;  // lanes 1, 2 and 8..11 zero
    EXPECT_EQ(simd::split_zero(z, 0, +1, 16), -1);
    EXPECT_EQ(simd::split_zero(z, 1, +1, 16), 2);
    EXPECT_EQ(simd::split_zero(z, 1, +1, 1), 1);    // no further than avail
    EXPECT_EQ(simd::split_zero(z, 3, +1, 16), -5);  // lanes 3..7
    EXPECT_EQ(simd::split_zero(z, 3, +1, 2), -2);
    EXPECT_EQ(simd::split_zero(z, 12, +1, 4), -4);
    EXPECT_EQ(simd::split_zero(z, 11, -1, 16), 4);  // lanes 11..8
    EXPECT_EQ(simd::split_zero(z, 7, -1, 16), -5);  // lanes 7..3
    EXPECT_EQ(simd::split_zero(z, 2, -1, 16), 2);   // lanes 2, 1
    EXPECT_EQ(simd::split_zero(z, 0, -1, 1), -1);
    EXPECT_EQ(simd::split_zero(z, 15, -1, 3), -3);
}

// An evaluated run of the skipping walk goes on to kLeastRun indices, never
// past the ray's end in its direction, and a longer run keeps its end.
TEST(Simd, LeastRunEndCoversKLeastRunWithinTheRay) {
    const std::int64_t L = simd::kLeastRun;
    EXPECT_EQ(simd::least_run_end(5, +1, 7, 1000), 5 + L - 1);
    EXPECT_EQ(simd::least_run_end(5, +1, 5 + L + 3, 1000), 5 + L + 3);  // longer: kept
    EXPECT_EQ(simd::least_run_end(5, +1, 7, 20), 20);                   // the ray ends first
    EXPECT_EQ(simd::least_run_end(100, -1, 98, 1), 100 - L + 1);
    EXPECT_EQ(simd::least_run_end(100, -1, 100 - L - 3, 1), 100 - L - 3);
    EXPECT_EQ(simd::least_run_end(20, -1, 18, 1), 1);
    EXPECT_EQ(simd::least_run_end(7, +1, 7, 7), 7);  // the last index
}

// Blocks of 2³ cells whose nodes all lie below E (simd::active_cells): their
// bits are clear exactly there (a NaN node sets them), and classify_batch,
// which stores a vector of samples in clear blocks as zero without
// interpolating, gives the very batches it gives without the bits.
TEST(Simd, InactiveBlocksGiveTheBatchesOfFullClassification) {
    const double e = 100.0;
    const Classifier c(tf(false), 1.0);
    const simd::FlatFunction fs = simd::flatten(c.sigma_function()), fc = simd::flatten(c.color_function());
    std::mt19937 rng(5);
    int skipped = 0;
    for (DType type : {DType::u8, DType::i8, DType::u16, DType::i16, DType::f32}) {
        Volume v = field(type);
        if (type == DType::i8) {  // the field shifted into int8's range
            const Volume f = field(DType::f32);
            for (std::int64_t k = 0; k < 27; ++k)
                for (std::int64_t j = 0; j < 19; ++j)
                    for (std::int64_t i = 0; i < 23; ++i) v.set_value(i, j, k, f.value(i, j, k) - 100.0);
        }
        if (type == DType::f32) v.set_value(1, 1, 1, std::numeric_limits<double>::quiet_NaN());
        const double ev = type == DType::i8 ? e - 100.0 : e;
        const std::vector<std::uint32_t> bits = simd::active_cells(v, ev, 2);
        ASSERT_FALSE(bits.empty()) << dtype_name(type);
        const auto& n = v.dims();
        int set = 0, clear = 0, wrong = 0;
        for (std::int64_t k = 0; k < n[2] / 2; ++k)
            for (std::int64_t j = 0; j < n[1] / 2; ++j)
                for (std::int64_t i = 0; i < n[0] / 2; ++i) {
                    bool any = false;  // a node of the block not below ev
                    for (std::int64_t z = 2 * k; z <= std::min(2 * k + 2, n[2] - 1); ++z)
                        for (std::int64_t y = 2 * j; y <= std::min(2 * j + 2, n[1] - 1); ++y)
                            for (std::int64_t x = 2 * i; x <= std::min(2 * i + 2, n[0] - 1); ++x)
                                any = any || !(v.value(x, y, z) < ev);
                    const std::int64_t b = i + n[0] / 2 * (j + n[1] / 2 * k);
                    const bool bit = ((bits[static_cast<std::size_t>(b >> 5)] >> (b & 31)) & 1u) != 0;
                    wrong += bit != any ? 1 : 0;
                    (bit ? set : clear) += 1;
                }
        EXPECT_EQ(wrong, 0) << dtype_name(type);
        EXPECT_GT(set, 50) << dtype_name(type);
        EXPECT_GT(clear, 50) << dtype_name(type);
        simd::BatchSource without{v.bytes(), type, n[0], n[1], n[2], &fs, &fc, ev};
        without.shared_knots = simd::same_knots(fs, fc);
        simd::BatchSource with = without;
        with.active = bits.data();
        std::uniform_real_distribution<double> pos(0.0, 1.0), dir(-1.0, 1.0);
        for (int r = 0; r < 300; ++r) {
            simd::RayGrid g;
            g.p0 = {pos(rng) * 22, pos(rng) * 18, pos(rng) * 26};
            g.dp = {dir(rng), dir(rng), dir(rng)};
            g.delta = 0.4;
            g.offset = 0.5;
            for (auto t : simd::available_targets()) {
                simd::force_target(t);
                simd::BatchOut a, b;
                simd::classify_batch(without, g, 1, simd::kBatch, a);
                simd::classify_batch(with, g, 1, simd::kBatch, b);
                EXPECT_EQ(a.zero, b.zero) << simd::active_target() << " ray " << r;
                EXPECT_EQ(std::memcmp(a.sigma, b.sigma, sizeof a.sigma), 0) << simd::active_target();
                EXPECT_EQ(std::memcmp(a.color, b.color, sizeof a.color), 0) << simd::active_target();
                skipped += a.zero == 0xFFFFu ? 1 : 0;
            }
            simd::force_target(0);
        }
    }
    EXPECT_GT(skipped, 100);  // batches below E throughout: where the bits can skip
}

namespace {

// Transfer functions that take every branch of pre-integration: jumps and
// a knot at a plateau (tf), Slicer's bone (absolute units), more than 32
// control values (the binary search), extinctions from 0 to 400, and a
// jump out of the medium's zero range (step).
std::vector<std::pair<std::string, Classifier>> ramp_tfs() {
    std::vector<std::pair<std::string, Classifier>> r;
    r.emplace_back("jumps", Classifier(tf(false), 1.0));
    r.emplace_back("jumps associated", Classifier(tf(true), 1.0));
    r.emplace_back("CT-Bone", Classifier(TransferFunction::preset("CT-Bone", {0, 1}), 0.5));
    TransferFunction many;
    many.alpha_kind = TransferFunction::Alpha::extinction;
    for (int i = 0; i < 40; ++i) {
        many.alpha_points.emplace_back(5.0 * i, i % 7 == 0 ? 0.0 : 0.05 * (i % 5) + (i == 20 ? 400.0 : 0.0));
        many.color_points.push_back({5.0 * i + 2.5, {0.1 * (i % 10), 0.5, 1.0 - 0.02 * i}});
    }
    r.emplace_back("many", Classifier(many, 1.0));
    TransferFunction step;  // a jump out of the zero range: σ's left limit at E is 0
    step.alpha_kind = TransferFunction::Alpha::extinction;
    step.alpha_points = {{20, 0.0}, {20, 0.3}, {70, 0.1}};
    step.color_points = {{10, {0, 0, 0}}, {20, {1, 1, 1}}, {50, {0.2, 0.4, 0.6}}};
    r.emplace_back("step", Classifier(step, 1.0));
    return r;
}

// The pre-integration batch source of c's transfer function (fs and fc its
// σ and color flattened; zero_below left for the model).
simd::BatchSource preint_source(const Classifier& c, const simd::FlatFunction& fs,
                                const simd::FlatFunction& fc) {
    simd::BatchSource src;
    src.sigma = &fs;
    src.color = &fc;
    src.shared_knots = simd::same_knots(fs, fc);
    src.breaks = &c.breakpoints();
    src.associated = c.associated();
    src.integrals = &c.integrals();
    return src;
}

}  // namespace

// Every lane against preintegrate_scalar: the same bits, or where the lanes
// fuse (simd_check.h) within the tolerance below.
TEST(SimdPreint, EverySegmentMatchesTheScalarCode) {
    std::mt19937 rng(7);
    long taken = 0, left = 0, integrals = 0, zero_pieces = 0;
    for (const auto& [name, c] : ramp_tfs()) {
        const auto& knots = c.breakpoints();
        // σ's and the source's largest values
        double sigma_max = 0.0, color_max = 0.0;
        for (const auto& y : c.sigma_function().values()) sigma_max = std::max(sigma_max, std::abs(y[0]));
        for (const auto& y : c.color_function().values())
            for (double x : y) color_max = std::max(color_max, std::abs(x));
        const double source_max = c.associated() ? color_max : sigma_max * color_max;
        const simd::FlatFunction fs = simd::flatten(c.sigma_function()),
                                 fc = simd::flatten(c.color_function());
        simd::BatchSource src = preint_source(c, fs, fc);
        // ends: random, control values exactly, repeats (constant ramps),
        // nearly repeats (about preint::kFlatRamp apart), NaN
        const double lo = knots.front() - 20, hi = knots.back() + 20;
        std::uniform_real_distribution<double> any(lo, hi);
        std::uniform_int_distribution<std::size_t> pick(0, knots.size() - 1);
        for (int trial = 0; trial < 60; ++trial) {
            // up to kBatch + 1 ends (kBatch segments), kBatch + 8 readable
            alignas(64) double ends[simd::kBatch + 8] = {};
            for (int j = 0; j <= simd::kBatch; ++j) {
                const int kind = static_cast<int>(rng() % 8);
                const double near = j > 0 ? ends[j - 1] + (std::abs(ends[j - 1] - knots.front()) + 1.0) *
                                                              preint::kFlatRamp * (kind == 2 ? 2.5 : 0.5)
                                          : 0.0;
                ends[j] = kind == 0                           ? knots[pick(rng)]
                          : kind == 1 && j > 0                ? ends[j - 1]
                          : (kind == 2 || kind == 3) && j > 0 ? near
                                                              : any(rng);
            }
            if (trial % 4 == 1) {  // every end between the same two control values: one piece per ramp
                const std::size_t k = pick(rng) % (knots.size() - 1);
                std::uniform_real_distribution<double> inside(knots[k], knots[k + 1]);
                for (int j = 0; j <= simd::kBatch; ++j) ends[j] = j % 5 == 4 ? ends[j - 1] : inside(rng);
            }
            if (trial == 5) ends[3] = std::numeric_limits<double>::quiet_NaN();
            const int count = 2 + trial % simd::kBatch;
            const std::uint32_t skip = trial % 3 == 0 ? 0x5u : 0u;
            for (Model model : {Model::emission_absorption, Model::absorption, Model::emission}) {
                // as the renderer sets it: the ramps leave out their pieces below it
                src.zero_below = zero_below(c, model);
                for (bool full : {true, false})
                    for (double delta : {0.01, 0.37, 3.0, 60.0})
                        for (auto t : simd::available_targets()) {
                            simd::force_target(t);
                            simd::SegmentBatch out;
                            simd::preintegrate_batch(src, model, full, delta, ends, count, skip, out);
                            for (int l = 0; l + 1 < count; ++l) {
                                if ((skip >> l) & 1u) {
                                    EXPECT_TRUE((out.scalar >> l) & 1u);
                                    continue;
                                }
                                if ((out.scalar >> l) & 1u) {
                                    ++left;
                                    continue;
                                }
                                ++taken;
                                if (!full && preint::steep_ramp(c.integrals(), ends[l], ends[l + 1]))
                                    ++integrals;
                                const double a = std::min(ends[l], ends[l + 1]),
                                             b = std::max(ends[l], ends[l + 1]);
                                zero_pieces += std::any_of(knots.begin(), knots.end(), [&](double k) {
                                    return a < k && k < b && k <= src.zero_below;
                                });
                                Segment want{};
                                switch (model) {
                                    case Model::absorption:
                                        want = preintegrate_scalar<Model::absorption>(c, ends[l], ends[l + 1],
                                                                                      delta, full);
                                        break;
                                    case Model::emission:
                                        want = preintegrate_scalar<Model::emission>(c, ends[l], ends[l + 1],
                                                                                    delta, full);
                                        break;
                                    default:
                                        want = preintegrate_scalar<Model::emission_absorption>(
                                            c, ends[l], ends[l + 1], delta, full);
                                }
                                const Segment got{
                                    out.transmittance[l],
                                    {out.radiance[0][l], out.radiance[1][l], out.radiance[2][l]}};
                                // a few ulp of double where the lanes fuse: relative to the
                                // value (the pieces' sums of positive terms; measured: 1e−14),
                                // and for the differences of the integral functions also to
                                // δ·σ_max (their own error, preint::kFlatRamp)
                                const bool simple =
                                    !full && preint::steep_ramp(c.integrals(), ends[l], ends[l + 1]);
                                auto close = [&](double g, double w, double largest) {
                                    return test::lanes_agree(
                                        g, w, 1e-12 * std::abs(w) + (simple ? 1e-8 * delta * largest : 0.0));
                                };
                                bool ok = close(got.transmittance, want.transmittance, sigma_max);
                                for (int k = 0; k < 3; ++k)
                                    ok = ok && close(got.radiance[k], want.radiance[k], source_max);
                                ASSERT_TRUE(ok) << simd::active_target() << " " << name << " "
                                                << to_string(model) << (full ? "" : " simple") << " δ "
                                                << delta << " ends " << ends[l] << " → " << ends[l + 1]
                                                << ": got " << got.transmittance << " " << got.radiance[0]
                                                << " want " << want.transmittance << " " << want.radiance[0];
                            }
                        }
            }
            simd::force_target(0);
        }
    }
    // nearly every segment is the vector code's; without self-attenuation
    // most take the integral functions; many ramps have pieces below zero_below
    EXPECT_GT(taken, 20 * left);
    EXPECT_GT(integrals, taken / 4);
    EXPECT_GT(zero_pieces, taken / 10);
}

// Segments packed from several windows, with a step each (the packets'
// pre-integration, simd::preintegrate_pack): every segment's bits, and the
// segments it leaves to the scalar code, are those of preintegrate_batch over
// the window it came from, on every target; the pack's last vector partial;
// from a later vector (`first`) too, and in a pack of two vectors or fewer
// (each vector's ramps piece by piece). Many ramps cross several knots, so
// that the lanes that go on past their first piece fill vectors of their own.
// The packs pick their cuts' control values from the padded table where
// they fit (BatchSource::break_table, as the renderer sets it), the windows
// gather them: the same bits.
TEST(SimdPreint, PackedSegmentsMatchTheirWindowsBitForBit) {
    std::mt19937 rng(11);
    long compared = 0, left = 0, many_pieces = 0;
    int tables = 0;
    for (const auto& [name, c] : ramp_tfs()) {
        const auto& knots = c.breakpoints();
        const simd::FlatFunction fs = simd::flatten(c.sigma_function()),
                                 fc = simd::flatten(c.color_function());
        simd::BatchSource src = preint_source(c, fs, fc);
        const simd::BreakTable table(knots);
        tables += table.get() != nullptr ? 1 : 0;
        std::uniform_real_distribution<double> any(knots.front() - 20, knots.back() + 20);
        std::uniform_int_distribution<std::size_t> pick(0, knots.size() - 1);
        // five windows of 2 … kBatch + 1 ends, each with its own step
        struct Window {
            alignas(64) double ends[simd::kBatch + 8] = {};
            int count = 0;
            double delta = 0;
            std::uint32_t skip = 0;
        };
        std::vector<Window> windows(5);
        for (std::size_t w = 0; w < windows.size(); ++w) {
            Window& win = windows[w];
            win.count = 2 + static_cast<int>(rng() % simd::kBatch);
            win.delta = std::array{0.01, 0.37, 3.0, 0.05, 0.5}[w];
            win.skip = w % 2 == 0 ? 0x9u : 0u;
            for (int j = 0; j < win.count; ++j)
                win.ends[j] = rng() % 4 == 0            ? knots[pick(rng)]
                              : rng() % 5 == 0 && j > 0 ? win.ends[j - 1]
                                                        : any(rng);
            if (w == 3) win.ends[1] = std::numeric_limits<double>::quiet_NaN();
        }
        auto wanted = [&] {
            int n = 0;
            for (const Window& win : windows)
                for (int l = 0; l + 1 < win.count; ++l) n += (win.skip >> l) & 1u ? 0 : 1;
            return n;
        };
        if (wanted() % 8 == 0) {  // a partial last vector on every target
            Window& last = windows.back();
            last.count += last.count <= simd::kBatch ? 1 : -1;
            last.ends[last.count - 1] = any(rng);
        }
        for (Model model : {Model::emission_absorption, Model::absorption, Model::emission}) {
            src.zero_below = zero_below(c, model);
            simd::BatchSource packed = src;
            packed.break_table = table.get();
            for (bool full : {true, false})
                for (auto t : simd::available_targets()) {
                    simd::force_target(t);
                    simd::SegmentPack pack;
                    for (const Window& win : windows)
                        for (int l = 0; l + 1 < win.count; ++l) {
                            if ((win.skip >> l) & 1u) continue;
                            pack.vf[pack.count] = win.ends[l];
                            pack.vb[pack.count] = win.ends[l + 1];
                            pack.delta[pack.count] = win.delta;
                            ++pack.count;
                        }
                    ASSERT_NE(pack.count % 8, 0);
                    // the same segments after 16 others (`first`): the same bits
                    simd::SegmentPack later;
                    std::fill(later.vf, later.vf + 16, knots.front());
                    std::fill(later.vb, later.vb + 16, knots.back());
                    std::fill(later.delta, later.delta + 16, 1.0);
                    std::copy(pack.vf, pack.vf + pack.count, later.vf + 16);
                    std::copy(pack.vb, pack.vb + pack.count, later.vb + 16);
                    std::copy(pack.delta, pack.delta + pack.count, later.delta + 16);
                    later.count = pack.count + 16;
                    // and the first 13 alone (a pack of two vectors or fewer)
                    simd::SegmentPack small;
                    small.count = std::min(pack.count, 13);
                    std::copy(pack.vf, pack.vf + small.count, small.vf);
                    std::copy(pack.vb, pack.vb + small.count, small.vb);
                    std::copy(pack.delta, pack.delta + small.count, small.delta);
                    simd::preintegrate_pack(packed, model, full, pack);
                    simd::preintegrate_pack(packed, model, full, later, 16);
                    simd::preintegrate_pack(packed, model, full, small);
                    auto same = [&](const simd::SegmentPack& other, int at, int count) {
                        for (int i = 0; i < count; ++i) {
                            ASSERT_EQ(other.scalar[at + i], pack.scalar[i]);
                            if (pack.scalar[i] != 0.0) continue;
                            EXPECT_EQ(std::memcmp(&other.transmittance[at + i], &pack.transmittance[i], 8),
                                      0);
                            for (int q = 0; q < 3; ++q)
                                EXPECT_EQ(std::memcmp(&other.radiance[q][at + i], &pack.radiance[q][i], 8),
                                          0);
                        }
                    };
                    same(later, 16, pack.count);
                    same(small, 0, small.count);
                    int k = 0;
                    for (const Window& win : windows) {
                        simd::SegmentBatch out;
                        simd::preintegrate_batch(src, model, full, win.delta, win.ends, win.count, win.skip,
                                                 out);
                        for (int l = 0; l + 1 < win.count; ++l) {
                            if ((win.skip >> l) & 1u) continue;
                            const bool scalar = ((out.scalar >> l) & 1u) != 0;
                            ASSERT_EQ(pack.scalar[k] != 0.0, scalar)
                                << simd::active_target() << " " << name << " segment " << l;
                            if (scalar) {
                                ++left;
                            } else {
                                ++compared;
                                const double lo = std::min(win.ends[l], win.ends[l + 1]),
                                             hi = std::max(win.ends[l], win.ends[l + 1]);
                                const auto inner = std::count_if(knots.begin(), knots.end(),
                                                                 [&](double v) { return lo < v && v < hi; });
                                many_pieces += inner >= 3 ? 1 : 0;
                                EXPECT_EQ(std::memcmp(&pack.transmittance[k], &out.transmittance[l], 8), 0);
                                for (int q = 0; q < 3; ++q)
                                    EXPECT_EQ(std::memcmp(&pack.radiance[q][k], &out.radiance[q][l], 8), 0)
                                        << simd::active_target() << " " << name << " " << to_string(model)
                                        << (full ? "" : " simple") << " segment " << l << ": "
                                        << pack.radiance[q][k] << " against " << out.radiance[q][l];
                            }
                            ++k;
                        }
                    }
                }
            simd::force_target(0);
        }
    }
    EXPECT_GT(compared, 10 * left);
    EXPECT_GT(left, 0);  // the NaN end's segments
    // ramps of four pieces and more: the pack's later rounds, in several vectors
    EXPECT_GT(many_pieces, compared / 10);
    EXPECT_GE(tables, 3);  // all but "many" (40 control values) and CT-Bone
}

TEST(SimdPreint, ExpNegIsWithinAFewUlpOfLibm) {
    std::mt19937_64 rng(3);
    std::uniform_real_distribution<double> any(-20.0, 720.0), small(0.0, 1.0);
    EXPECT_EQ(preint::exp_neg(0.0), 1.0);
    EXPECT_EQ(preint::exp_neg(-0.0), 1.0);
    EXPECT_EQ(preint::exp_neg(800.0), 0.0);  // beyond the reduction: libm
    EXPECT_EQ(preint::one_minus_exp_neg(0.0), 0.0);
    EXPECT_EQ(preint::one_minus_exp_neg(800.0), 1.0);
    EXPECT_TRUE(std::isnan(preint::exp_neg(std::numeric_limits<double>::quiet_NaN())));
    for (int i = 0; i < 200000; ++i) {
        const double x = i % 2 == 0 ? any(rng) : small(rng);
        const double want = std::exp(-x), ulp = std::nextafter(want, INFINITY) - want;
        ASSERT_LE(std::abs(preint::exp_neg(x) - want), 2 * ulp) << x;
        // 1 − e^{−x}, also for tiny x
        const double y = i % 3 == 0 ? x * 1e-9 : x, m = -std::expm1(-y);
        ASSERT_LE(std::abs(preint::one_minus_exp_neg(y) - m), 4 * (std::nextafter(m, INFINITY) - m)) << y;
        // the thin pieces' degree-7 series on [0, 1/4]: truncation < 4e−10
        const double t = 0.25 * small(rng);
        ASSERT_LE(std::abs(preint::exp_neg_thin(t) - std::exp(-t)), 4e-10) << t;
    }
    EXPECT_EQ(preint::exp_neg_thin(0.0), 1.0);
    EXPECT_GT(std::abs(preint::exp_neg_thin(0.25) - std::exp(-0.25)), 1e-12);  // a truncated series, not libm
}

// The segment rules classify_batch applies (BatchSource::rule): every lane,
// every target, against point_rules.h on the scalar path's σ and g, bit for
// bit; optical depths beyond exp_neg's reduction (σ up to 400, δ up to 50)
// and NaN scalars included, and zero lanes (1, 0). Where the lanes fuse
// (simd_check.h) the rules take the batch's own scalars (batch_matches_sampler
// checks those) and agree to 1e−12 relative (t also to 1e−15: 1 − α).
TEST(Simd, SegmentRulesMatchTheScalarRules) {
    std::mt19937 rng(13);
    long compared = 0, deep = 0;
    for (const auto& [name, c] : ramp_tfs()) {
        const auto& knots = c.breakpoints();
        const simd::FlatFunction fs = simd::flatten(c.sigma_function()),
                                 fc = simd::flatten(c.color_function());
        std::uniform_real_distribution<double> value(knots.front() - 20, knots.back() + 20);
        Volume v({6, 5, 4}, DType::f32);
        for (std::int64_t k = 0; k < 4; ++k)
            for (std::int64_t j = 0; j < 5; ++j)
                for (std::int64_t i = 0; i < 6; ++i)
                    v.set_value(i, j, k,
                                (i + j + k) % 11 == 5 ? std::numeric_limits<double>::quiet_NaN()
                                : (i + j) % 5 == 0    ? knots[static_cast<std::size_t>(i + k) % knots.size()]
                                                      : value(rng));
        const GridSampler<float> sampler(v);
        for (auto model : {Model::emission_absorption, Model::absorption, Model::emission})
            for (auto rule : {simd::PointRule::alpha, simd::PointRule::riemann}) {
                simd::BatchSource src{v.bytes(), DType::f32, 6, 5, 4, &fs, &fc, zero_below(c, model)};
                src.shared_knots = simd::same_knots(fs, fc);
                src.associated = c.associated();
                src.rule = rule;
                src.model = model;
                std::uniform_real_distribution<double> pos(0.0, 1.0), dir(-1.0, 1.0);
                for (int r = 0; r < 40; ++r) {
                    simd::RayGrid g;
                    g.delta = std::array{0.013, 0.4, 5.0, 50.0}[static_cast<std::size_t>(r % 4)];
                    // inside the lattice, as the renderer's samples: 1.4 cells along the batch at most
                    const double reach = 1.4 / (simd::kBatch * g.delta);
                    g.p0 = {1.5 + pos(rng) * 2, 1.5 + pos(rng) * 1.5, 1.5 + pos(rng)};
                    g.dp = {dir(rng) * reach, dir(rng) * reach, dir(rng) * reach};
                    g.offset = 0.5;
                    for (auto t : simd::available_targets()) {
                        simd::force_target(t);
                        simd::BatchOut out;
                        simd::classify_batch(src, g, 1, simd::kBatch, out);
                        alignas(64) double values[simd::kBatch];
                        simd::interpolate_batch(src, g, 1, simd::kBatch, values, nullptr);
                        const bool fused = simd::fused_lanes();
                        for (int l = 0; l < simd::kBatch; ++l) {
                            const double s =
                                fused ? values[l]
                                      : sampler(g.p0 + g.dp * (g.t_near + (l + g.offset) * g.delta));
                            MediumSample m{c.sigma(s), c.color(s)};
                            if (!c.associated())
                                for (double& x : m.source) x *= m.sigma;
                            if (model == Model::absorption) m.source = {0, 0, 0};
                            if (model == Model::emission) m.sigma = 0.0;
                            if (((out.zero >> l) & 1u) != 0) m = {};  // below zero_below: exactly zero
                            const Segment want = rule == simd::PointRule::alpha ? alpha_segment(m, g.delta)
                                                                                : riemann_segment(m, g.delta);
                            const double wt = want.transmittance;
                            ASSERT_TRUE(test::lanes_agree(out.t[l], wt, 1e-12 * std::abs(wt) + 1e-15))
                                << simd::active_target() << " " << name << " " << to_string(model) << " lane "
                                << l << " δ " << g.delta << ": " << out.t[l] << " against " << wt;
                            for (int k = 0; k < 3; ++k) {
                                const double wr = want.radiance[k];
                                ASSERT_TRUE(test::lanes_agree(out.radiance[k][l], wr, 1e-12 * std::abs(wr)))
                                    << simd::active_target() << " " << name << " channel " << k << ": "
                                    << out.radiance[k][l] << " against " << wr;
                            }
                            deep += !(m.sigma * g.delta <= 708.0) ? 1 : 0;
                            ++compared;
                        }
                    }
                    simd::force_target(0);
                }
            }
    }
    EXPECT_GE(compared, 4 * 3 * 2 * 40 * simd::kBatch);
    EXPECT_GT(deep, 100);  // lanes the scalar rule takes over
}

// The pixel bounds' boxes projected in vectors (simd::project_boxes) against
// the scalar corners, bit for bit on every target: perspective and
// orthographic cameras, macrocells of 2 and 4 cells with the last ones
// clipped, a count that leaves a partial vector, and boxes that reach
// behind the eye (infinite and NaN pixel coordinates, which std::min and
// std::max pass over where the first argument is a number).
TEST(Simd, BoxProjectionMatchesTheScalarCorners) {
    std::mt19937 rng(29);
    std::uniform_real_distribution<double> u(-1.0, 1.0);
    long compared = 0, nonfinite = 0;
    for (int trial = 0; trial < 12; ++trial) {
        simd::BoxProjection p;
        p.perspective = trial % 3 != 2;
        p.shift = 1 + trial % 2;
        p.margin = 1.0 / 64;
        p.dims = {5 + trial % 4, 3 + trial % 3, 4 + trial % 5};
        for (std::size_t a = 0; a < 3; ++a)  // the last macrocell clipped on some axes
            p.nodes[a] = (p.dims[a] << p.shift) + 1 - ((trial + static_cast<int>(a)) % 2);
        for (auto& c : p.col) c = {u(rng) * 0.8, u(rng) * 0.8, u(rng) * 0.8};
        p.c0 = {u(rng) * 10, u(rng) * 10, 40 + 10 * u(rng)};  // in front of the eye
        if (trial % 4 == 3) {  // but box 0's first corner at c.x = c.z = 3/128 − 3·(1/64)·(1/2) = 0: px NaN
            for (auto& c : p.col) c.x = c.z = 0.5;
            p.c0.x = p.c0.z = 3.0 / 128;
        }
        p.scale_x = 300 + 50 * u(rng);
        p.scale_y = 280 + 50 * u(rng);
        p.bx = 255.5;
        p.by = 199.5;
        const auto cells = static_cast<std::uint32_t>(p.dims[0] * p.dims[1] * p.dims[2]);
        std::vector<std::uint32_t> index;
        for (std::uint32_t i = 0; i < cells; i += 1 + static_cast<std::uint32_t>(trial % 2))
            index.push_back(i);
        const std::size_t n = index.size() - 3;  // a partial vector at the end
        // the scalar projection, as EmptySpace::pixel_bounds computed it per box
        std::vector<std::array<double, 6>> want(n);
        for (std::size_t b = 0; b < n; ++b) {
            std::int64_t i = index[b];
            std::array<double, 3> lo{}, hi{};
            for (std::size_t a = 0; a < 3; ++a) {
                const std::int64_t ma = i % p.dims[a];
                i /= p.dims[a];
                lo[a] = static_cast<double>(ma << p.shift) - p.margin;
                hi[a] = static_cast<double>(std::min((ma + 1) << p.shift, p.nodes[a] - 1)) + p.margin;
            }
            Vec3 first = p.c0;
            for (std::size_t a = 0; a < 3; ++a) first += p.col[a] * lo[a];
            const Vec3 edge[3] = {p.col[0] * (hi[0] - lo[0]), p.col[1] * (hi[1] - lo[1]),
                                  p.col[2] * (hi[2] - lo[2])};
            double x0 = INFINITY, x1 = -INFINITY, y0 = INFINITY, y1 = -INFINITY;
            double z0 = INFINITY, z1 = -INFINITY, far2 = 0.0;
            for (int k = 0; k < 8; ++k) {
                Vec3 c = first;
                for (int a = 0; a < 3; ++a)
                    if (((k >> a) & 1) != 0) c += edge[a];
                const double s = p.perspective ? 1.0 / c.z : 1.0;
                const double px = c.x * s * p.scale_x + p.bx, py = p.by - c.y * s * p.scale_y;
                x0 = std::min(x0, px);
                x1 = std::max(x1, px);
                y0 = std::min(y0, py);
                y1 = std::max(y1, py);
                z0 = std::min(z0, c.z);
                z1 = std::max(z1, c.z);
                far2 = std::max(far2, dot(c, c));
            }
            double t0 = z0, t1 = z1;
            if (p.perspective) {
                const Vec3 half = (edge[0] + edge[1] + edge[2]) * 0.5;
                t0 = std::max(z0, length(first + half) - length(half));
                t1 = std::sqrt(far2);
            }
            want[b] = {x0, x1, y0, y1, t0, t1};
            nonfinite += std::isfinite(x0 + x1 + y0 + y1) ? 0 : 1;
        }
        for (auto t : simd::available_targets()) {
            simd::force_target(t);
            std::vector<double> got[6];
            for (auto& g : got) g.assign(n + 8, 0.0);
            simd::project_boxes(
                p, index.data(), n,
                {got[0].data(), got[1].data(), got[2].data(), got[3].data(), got[4].data(), got[5].data()});
            for (std::size_t b = 0; b < n; ++b)
                for (std::size_t k = 0; k < 6; ++k) {
                    ASSERT_EQ(std::bit_cast<std::uint64_t>(got[k][b]),
                              std::bit_cast<std::uint64_t>(want[b][k]))
                        << simd::active_target() << " trial " << trial << " box " << b << " value " << k
                        << ": " << got[k][b] << " against " << want[b][k];
                    ++compared;
                }
        }
        simd::force_target(0);
    }
    EXPECT_GT(compared, 1000);
    EXPECT_GT(nonfinite, 0);  // boxes across the eye's plane were among them
}

// The footprints of boxes' images (simd::footprints) against
// simd::footprint_of, and their drawing (simd::draw_footprints) against
// std::min and std::max pixel by pixel, bit for bit on every target: images
// inside, across and outside the image's edges, rows that end at its last
// column (the vector tail cannot reach past the row there), non-finite
// images, and t whose nearest float lies above or below it, at ±0, past
// FLT_MAX and at ±∞.
TEST(Simd, FootprintsAndTheirDrawingMatchTheScalarRule) {
    std::mt19937 rng(41);
    std::uniform_real_distribution<double> u(0.0, 1.0);
    long compared = 0, stepped = 0, whole = 0, drawn = 0;
    for (int trial = 0; trial < 8; ++trial) {
        const simd::FootprintRule rule{37 + 11 * trial, 23 + 7 * trial, 1.0 / 16,
                                       trial % 2 == 0 ? 1e-6 : 0.0};
        const std::size_t n = 200 + static_cast<std::size_t>(trial) * 13;
        std::vector<double> image[6];
        for (auto& v : image) v.assign(n + 16, 0.0);
        for (std::size_t b = 0; b < n; ++b) {
            const double cx = (u(rng) * 1.4 - 0.2) * rule.width, cy = (u(rng) * 1.4 - 0.2) * rule.height;
            const double rx = u(rng) * (b % 5 == 0 ? 40 : 6), ry = u(rng) * 6;
            image[0][b] = cx - rx;
            image[1][b] = b % 7 == 0 ? rule.width - 1 + u(rng) * 0.05 : cx + rx;  // to the last column
            image[2][b] = cy - ry;
            image[3][b] = cy + ry;
            const double t = 1 + 400 * u(rng);
            const double special[] = {0.0, -0.0, 1e-300, -1e-300, 4e38, -4e38, 0.1, -0.1};
            image[4][b] = b % 11 == 0 ? special[(b / 11) % 8] : t;
            image[5][b] = b % 13 == 0 ? special[(b / 13 + 3) % 8] : t + 10 * u(rng);
            if (b % 17 == 0) image[b % 6][b] = b % 34 == 0 ? INFINITY : NAN;
            if (b % 19 == 0) image[4][b] = -INFINITY;
        }
        std::vector<std::int32_t> want_rect(4 * n);
        std::vector<float> want_t(2 * n);
        const auto pixels = static_cast<std::size_t>(rule.width * rule.height);
        std::vector<float> want_lo(pixels, INFINITY), want_hi(pixels, -INFINITY);
        std::vector<std::size_t> draw;
        for (std::size_t b = 0; b < n; ++b) {
            const double box[6] = {image[0][b], image[1][b], image[2][b],
                                   image[3][b], image[4][b], image[5][b]};
            simd::footprint_of(rule, box, &want_rect[4 * b], &want_t[2 * b]);
            whole += std::isfinite(box[0] + box[1] + box[2] + box[3] + box[4] + box[5]) ? 0 : 1;
            stepped += static_cast<double>(want_t[2 * b]) != box[4] - rule.t_slack ? 1 : 0;
            // drawn: the finite images with ordinary t (a whole image's (−∞, ∞) would hide the rest)
            if (!std::isfinite(box[0] + box[1] + box[2] + box[3] + box[4] + box[5]) || b % 11 == 0 ||
                b % 13 == 0)
                continue;
            draw.push_back(b);
            for (int y = want_rect[4 * b + 2]; y <= want_rect[4 * b + 3]; ++y)
                for (int x = want_rect[4 * b]; x <= want_rect[4 * b + 1]; ++x) {
                    const auto k = static_cast<std::size_t>(y * rule.width + x);
                    want_lo[k] = std::min(want_lo[k], want_t[2 * b]);
                    want_hi[k] = std::max(want_hi[k], want_t[2 * b + 1]);
                    ++drawn;
                }
        }
        for (auto t : simd::available_targets()) {
            simd::force_target(t);
            std::vector<std::int32_t> rect[4];
            std::vector<float> ts[2];
            for (auto& r : rect) r.assign(n + 16, -7);
            for (auto& v : ts) v.assign(n + 16, -7.0f);
            const simd::Footprints fp{rect[0].data(), rect[1].data(), rect[2].data(),
                                      rect[3].data(), ts[0].data(),   ts[1].data()};
            simd::footprints(rule,
                             {image[0].data(), image[1].data(), image[2].data(), image[3].data(),
                              image[4].data(), image[5].data()},
                             n, fp);
            for (std::size_t b = 0; b < n; ++b) {
                for (std::size_t k = 0; k < 4; ++k)
                    ASSERT_EQ(rect[k][b], want_rect[4 * b + k])
                        << simd::active_target() << " trial " << trial << " box " << b << " rect " << k;
                for (std::size_t k = 0; k < 2; ++k)
                    ASSERT_EQ(std::bit_cast<std::uint32_t>(ts[k][b]),
                              std::bit_cast<std::uint32_t>(want_t[2 * b + k]))
                        << simd::active_target() << " trial " << trial << " box " << b << " t " << k << ": "
                        << ts[k][b] << " against " << want_t[2 * b + k];
                ++compared;
            }
            for (std::size_t k = 0; k < draw.size(); ++k) {  // those footprints, in front
                for (auto& r : rect) r[k] = r[draw[k]];
                for (auto& v : ts) v[k] = v[draw[k]];
            }
            std::vector<float> lo(pixels, INFINITY), hi(pixels, -INFINITY);
            simd::draw_footprints(fp, draw.size(), rule.width, lo.data(), hi.data());
            for (std::size_t k = 0; k < pixels; ++k) {
                ASSERT_EQ(std::bit_cast<std::uint32_t>(lo[k]), std::bit_cast<std::uint32_t>(want_lo[k]))
                    << simd::active_target() << " trial " << trial << " pixel " << k;
                ASSERT_EQ(std::bit_cast<std::uint32_t>(hi[k]), std::bit_cast<std::uint32_t>(want_hi[k]))
                    << simd::active_target() << " trial " << trial << " pixel " << k;
            }
        }
        simd::force_target(0);
    }
    EXPECT_GT(compared, 1000);
    EXPECT_GT(whole, 10);     // non-finite images took the whole image
    EXPECT_GT(stepped, 100);  // nearest floats on the wrong side, stepped
    EXPECT_GT(drawn, 5000);
}
