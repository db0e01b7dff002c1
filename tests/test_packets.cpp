// Ray packets (simd::trace_packets, RenderSettings::packets): the
// point-sampled quadratures and pre-integration traced one ray per SIMD
// lane must give the very bits of tracing the rays one by one, for every
// sample type, integrator, model, sample point, background, termination
// threshold, layout and SIMD target, and where the exponential's range runs
// out. The renderer takes them only where they repeat that path.
#include <cmath>
#include <cstring>
#include <limits>
#include <random>

#include <gtest/gtest.h>

#include "fathom/io.h"
#include "fathom/render.h"

#include "integrate/simd_classify.h"
#include "synthetic.h"
#include "test_util.h"

using namespace fathom;

namespace {

bool same_pixels(const Image& a, const Image& b) {
    return a.width == b.width && a.height == b.height && a.rgba.size() == b.rgba.size() &&
           std::memcmp(a.rgba.data(), b.rgba.data(), sizeof(float) * a.rgba.size()) == 0;
}

// Shells of a few voxels around two centres, in a box whose cell counts
// are not multiples of the macrocell edge, scaled to [lo, hi] and stored as
// `type`: rays cross empty space, thin walls and the zero range in turn.
Volume shells(DType type, double lo, double hi, std::array<std::int64_t, 3> dims = {41, 35, 38}) {
    Volume v(dims, type);
    for (std::int64_t k = 0; k < dims[2]; ++k)
        for (std::int64_t j = 0; j < dims[1]; ++j)
            for (std::int64_t i = 0; i < dims[0]; ++i) {
                auto shell = [&](double cx, double cy, double cz, double r) {
                    const double d =
                        std::sqrt((i - cx) * (i - cx) + (j - cy) * (j - cy) + (k - cz) * (k - cz));
                    return std::max(0.0, 1.0 - std::abs(d - r) / 2.5);
                };
                const double f = std::min(1.0, shell(15, 16, 17, 10) + shell(27, 19, 22, 7));
                double x = lo + (hi - lo) * f;
                if (type != DType::f32 && type != DType::f64) x = std::round(x);
                v.set_value(i, j, k, x);
            }
    v.set_spacing({1.0, 1.2, 0.9});
    return v;
}

// σ exactly 0 below a third of the range, a ramp, a jump; colors vary.
TransferFunction shell_tf(double lo, double hi, bool associated = false, double scale = 1.0) {
    auto at = [&](double f) { return lo + (hi - lo) * f; };
    TransferFunction tf;
    tf.alpha_kind = TransferFunction::Alpha::extinction;
    tf.alpha_points = {{at(0.0), 0.0},         {at(0.33), 0.0},        {at(0.5), 0.6 * scale},
                       {at(0.7), 0.6 * scale}, {at(0.7), 2.0 * scale}, {at(1.0), 2.5 * scale}};
    tf.associated = associated;
    if (associated)
        tf.color_points = {
            {at(0.0), {0, 0, 0}}, {at(0.2), {0, 0, 0}}, {at(0.6), {0.7, 0.3, 0.1}}, {at(1.0), {1, 1, 0.4}}};
    else
        tf.color_points = {{at(0.0), {0.2, 0.4, 0.9}}, {at(0.5), {0.9, 0.5, 0.2}}, {at(1.0), {1, 1, 1}}};
    return tf;
}

RenderSettings packet_settings(IntegratorKind k, Model m) {
    RenderSettings s;
    s.width = 37;
    s.height = 29;
    s.integrator = k;
    s.model = m;
    s.step = 0.6;
    s.threads = 2;
    return s;
}

// Renders with packets on and off for each camera; the number of images
// that differ in any bit. Fails the test if the renderer does not take
// packets where asked.
int compare(const Volume& v, const TransferFunction& tf, RenderSettings s, const std::vector<Camera>& cams) {
    s.packets = false;
    const Renderer one_by_one(v, tf, s);
    s.packets = true;
    const Renderer packets(v, tf, s);
    EXPECT_FALSE(one_by_one.packets());
    EXPECT_TRUE(packets.packets());
    int bad = 0;
    for (const Camera& cam : cams)
        if (!same_pixels(packets.render(cam), one_by_one.render(cam))) ++bad;
    return bad;
}

struct Range {
    DType type;
    double lo, hi;
};
constexpr Range kTypes[] = {{DType::u8, 0, 250},       {DType::i8, -120, 120}, {DType::u16, 100, 60000},
                            {DType::i16, -2000, 3000}, {DType::u32, 0, 1e6},   {DType::i32, -5e5, 5e5},
                            {DType::f32, -1.5, 2.5},   {DType::f64, 0, 1}};

}  // namespace

TEST(Packets, RendererTakesThemWhereTheyRepeatThePointSampledWalk) {
    const Volume v = shells(DType::u8, 0, 250);
    const TransferFunction tf = shell_tf(0, 250);
    auto takes = [&](auto&& change) {
        RenderSettings s = packet_settings(IntegratorKind::alpha, Model::emission_absorption);
        change(s);
        return Renderer(v, tf, s).packets();
    };
    EXPECT_TRUE(takes([](RenderSettings&) {}));
    EXPECT_TRUE(takes([](RenderSettings& s) { s.integrator = IntegratorKind::riemann; }));
    EXPECT_TRUE(takes([](RenderSettings& s) { s.model = Model::absorption; }));
    EXPECT_TRUE(takes([](RenderSettings& s) { s.sample_point = SamplePoint::mid; }));
    EXPECT_FALSE(takes([](RenderSettings& s) { s.packets = false; }));
    EXPECT_FALSE(takes([](RenderSettings& s) { s.order = Order::back_to_front; }));
    EXPECT_TRUE(takes([](RenderSettings& s) { s.integrator = IntegratorKind::preintegrated; }));
    EXPECT_TRUE(takes([](RenderSettings& s) { s.integrator = IntegratorKind::preintegrated_simple; }));
    EXPECT_FALSE(takes([](RenderSettings& s) {
        s.integrator = IntegratorKind::preintegrated;
        s.order = Order::back_to_front;
    }));
    EXPECT_TRUE(takes([](RenderSettings& s) {
        s.integrator = IntegratorKind::preintegrated;
        s.shading.enabled = true;
    }));
    EXPECT_FALSE(takes([](RenderSettings& s) { s.integrator = IntegratorKind::reference; }));
    EXPECT_TRUE(takes([](RenderSettings& s) { s.shading.enabled = true; }));
    EXPECT_TRUE(takes([](RenderSettings& s) {
        s.shading.enabled = true;
        s.integrator = IntegratorKind::riemann;
    }));
    EXPECT_FALSE(takes([](RenderSettings& s) {  // node gradients: the tracer shades sample by sample
        s.shading.enabled = true;
        s.gradient = GradientSource::precomputed;
    }));
    EXPECT_FALSE(takes([](RenderSettings& s) {
        s.shading.enabled = true;
        s.order = Order::back_to_front;
    }));
    EXPECT_TRUE(takes([](RenderSettings& s) { s.jitter = true; }));
    EXPECT_TRUE(takes([](RenderSettings& s) { s.depth_outputs = true; }));
    EXPECT_TRUE(takes([](RenderSettings& s) {
        s.depth_outputs = true;
        s.integrator = IntegratorKind::preintegrated;
    }));
    // without skipping: a walk of macrocells none of which is empty
    EXPECT_TRUE(takes([](RenderSettings& s) { s.skip_empty = false; }));
    EXPECT_TRUE(takes([](RenderSettings& s) {
        s.skip_empty = false;
        s.integrator = IntegratorKind::preintegrated;
    }));
    EXPECT_FALSE(takes([](RenderSettings& s) {
        s.skip_empty = false;
        s.integrator = IntegratorKind::preintegrated;
        s.order = Order::back_to_front;
    }));
    EXPECT_FALSE(takes([](RenderSettings& s) { s.simd = false; }));
    EXPECT_FALSE(takes([](RenderSettings& s) { s.model = Model::mip; }));
}

// Where nothing is skipped (skipping off, or a transfer function with no
// zero range), packets walk macrocells none of which is empty: the same
// bits as the one-by-one path's single run per ray (point-sampled) or its
// windows over every segment (pre-integrated).
TEST(Packets, FramesThatSkipNothingAreBitIdentical) {
    const Volume v = shells(DType::u16, 100, 60000);
    const auto cams = test::comparison_cameras(v);
    TransferFunction everywhere = shell_tf(100, 60000);
    everywhere.alpha_points.front().second = 0.05;
    everywhere.alpha_points[1].second = 0.05;
    for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated,
                   IntegratorKind::preintegrated_simple}) {
        RenderSettings s = packet_settings(k, Model::emission_absorption);
        s.skip_empty = false;
        EXPECT_EQ(compare(v, shell_tf(100, 60000), s, cams), 0) << to_string(k) << " without skipping";
        s.skip_empty = true;
        EXPECT_EQ(compare(v, everywhere, s, cams), 0) << to_string(k) << " nothing empty";
        EXPECT_EQ(Renderer(v, everywhere, s).macrocell_cells(), 0);
    }
}

// Pre-integration takes packets only where empty macrocells join: here a
// block of constant value whose σ and g are 0 above the ramp is empty but
// not below the zero range, so a segment between two empty boxes need not
// be (1, 0).
TEST(Packets, PreIntegrationTakesThemWhereEmptyMacrocellsJoin) {
    Volume v({33, 30, 31}, DType::u8);
    for (std::int64_t k = 0; k < 31; ++k)
        for (std::int64_t j = 0; j < 30; ++j)
            for (std::int64_t i = 0; i < 33; ++i) v.set_value(i, j, k, i < 16 ? 0.0 : i < 18 ? 120.0 : 240.0);
    TransferFunction tf;
    tf.alpha_kind = TransferFunction::Alpha::extinction;
    tf.alpha_points = {{0, 0}, {80, 0}, {120, 0.5}, {160, 0}, {250, 0}};
    tf.color_points = {{0, {1, 1, 1}}, {250, {1, 0.5, 0.2}}};
    RenderSettings s = packet_settings(IntegratorKind::preintegrated, Model::emission_absorption);
    EXPECT_FALSE(Renderer(v, tf, s).packets());
    tf.alpha_points = {{0, 0}, {80, 0}, {120, 0.5}, {250, 0.6}};
    EXPECT_TRUE(Renderer(v, tf, s).packets());
}

TEST(Packets, PreIntegrationIsBitIdenticalToItsWindows) {
    int compared = 0;
    for (const Range& r : kTypes) {
        const Volume v = shells(r.type, r.lo, r.hi);
        const auto cams = test::comparison_cameras(v);
        for (auto k : {IntegratorKind::preintegrated, IntegratorKind::preintegrated_simple})
            for (auto m : {Model::emission_absorption, Model::absorption, Model::emission})
                for (bool associated : {false, true}) {
                    EXPECT_EQ(compare(v, shell_tf(r.lo, r.hi, associated), packet_settings(k, m), cams), 0)
                        << dtype_name(r.type) << " " << to_string(k) << " " << to_string(m)
                        << (associated ? " associated" : "");
                    compared += static_cast<int>(cams.size());
                }
    }
    EXPECT_EQ(compared, 8 * 2 * 3 * 2 * 4);
}

TEST(Packets, ImagesAreBitIdenticalToTracingRaysOneByOne) {
    int compared = 0;
    for (const Range& r : kTypes) {
        const Volume v = shells(r.type, r.lo, r.hi);
        const auto cams = test::comparison_cameras(v);
        for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann})
            for (auto m : {Model::emission_absorption, Model::absorption, Model::emission})
                for (bool associated : {false, true}) {
                    RenderSettings s = packet_settings(k, m);
                    s.sample_point = associated ? SamplePoint::mid : SamplePoint::near;
                    EXPECT_EQ(compare(v, shell_tf(r.lo, r.hi, associated), s, cams), 0)
                        << dtype_name(r.type) << " " << to_string(k) << " " << to_string(m)
                        << (associated ? " associated, midpoints" : "");
                    compared += static_cast<int>(cams.size());
                }
    }
    EXPECT_EQ(compared, 8 * 2 * 3 * 2 * 4);
}

// σ and c with the same knots (a jump among them), as the CT presets have:
// the packets then locate a sample's piece once for both.
TEST(Packets, OpacityAndColorOnTheSameKnotsAreBitIdentical) {
    for (const Range& r : kTypes) {
        const Volume v = shells(r.type, r.lo, r.hi);
        const auto cams = test::comparison_cameras(v);
        auto at = [&](double f) { return r.lo + (r.hi - r.lo) * f; };
        TransferFunction tf;
        tf.alpha_kind = TransferFunction::Alpha::extinction;
        tf.alpha_points = {{at(0.0), 0.0}, {at(0.33), 0.0}, {at(0.5), 0.6},
                           {at(0.7), 0.6}, {at(0.7), 2.0},  {at(1.0), 2.5}};
        tf.color_points = {{at(0.0), {0, 0, 0}},       {at(0.33), {0.2, 0.4, 0.9}},
                           {at(0.5), {0.9, 0.5, 0.2}}, {at(0.7), {0.9, 0.6, 0.3}},
                           {at(0.7), {1, 0.9, 0.8}},   {at(1.0), {1, 1, 1}}};
        for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated})
            EXPECT_EQ(compare(v, tf, packet_settings(k, Model::emission_absorption), cams), 0)
                << dtype_name(r.type) << " " << to_string(k);
    }
}

// Early termination at several thresholds (none, the default, a high one
// that stops most rays in their first wall), backgrounds with −0, one
// thread and two, a step that puts several samples in a cell and one that
// crosses a macrocell in two.
TEST(Packets, TerminationBackgroundsThreadsAndStepsAreBitIdentical) {
    const Volume v = shells(DType::u16, 100, 60000);
    const auto cams = test::comparison_cameras(v);
    const TransferFunction tf = shell_tf(100, 60000, false, 3.0);
    for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated})
        for (double termination : {0.0, 1e-3, 0.4})
            for (const Rgb& bg : {Rgb{0, 0, 0}, Rgb{0.2, -0.0, 0.7}})
                for (int threads : {1, 2})
                    for (double step : {0.23, 1.7}) {
                        RenderSettings s = packet_settings(k, Model::emission_absorption);
                        s.termination = termination;
                        s.background = bg;
                        s.threads = threads;
                        s.step = step;
                        EXPECT_EQ(compare(v, tf, s, cams), 0)
                            << to_string(k) << " termination " << termination << " background " << bg[1]
                            << " threads " << threads << " step " << step;
                    }
}

// Every SIMD target's packets against its own ray-by-ray path: with fused
// multiply–adds the targets differ from each other, never from themselves.
TEST(Packets, EveryTargetIsBitIdenticalToItsRayByRayPath) {
    const auto targets = simd::available_targets();
    ASSERT_FALSE(targets.empty());
    int compared = 0;
    for (const Range& r : {kTypes[1], kTypes[3], kTypes[6]}) {
        const Volume v = shells(r.type, r.lo, r.hi);
        const auto cams = test::comparison_cameras(v);
        for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated,
                       IntegratorKind::preintegrated_simple})
            for (auto t : targets) {
                simd::force_target(t);
                EXPECT_EQ(
                    compare(v, shell_tf(r.lo, r.hi), packet_settings(k, Model::emission_absorption), cams), 0)
                    << simd::active_target() << " " << dtype_name(r.type) << " " << to_string(k);
                ++compared;
            }
        simd::force_target(0);
    }
    EXPECT_EQ(compared, 3 * 4 * static_cast<int>(targets.size()));
}

// Optical depths σδ outside the vector exponential's range take the scalar
// rule lane by lane (as ApplyRule does), and NaN nodes are never skipped:
// the same bits, NaN payloads included.
TEST(Packets, ExtinctionBeyondTheExponentialsRangeAndNanNodesAreBitIdentical) {
    const Volume v = shells(DType::f32, -1.5, 2.5);
    const auto cams = test::comparison_cameras(v);
    for (double scale : {1e3, 1e300}) {
        EXPECT_EQ(compare(v, shell_tf(-1.5, 2.5, false, scale),
                          packet_settings(IntegratorKind::alpha, Model::emission_absorption), cams),
                  0)
            << "σ scaled by " << scale;
        EXPECT_EQ(compare(v, shell_tf(-1.5, 2.5, false, scale),
                          packet_settings(IntegratorKind::riemann, Model::absorption), cams),
                  0)
            << "σ scaled by " << scale;
        // segments the SIMD lanes leave to the scalar code (PacketPreint::scalar)
        EXPECT_EQ(compare(v, shell_tf(-1.5, 2.5, false, scale),
                          packet_settings(IntegratorKind::preintegrated, Model::emission_absorption), cams),
                  0)
            << "σ scaled by " << scale;
    }
    Volume nan = v;
    nan.set_value(20, 17, 19, std::numeric_limits<double>::quiet_NaN());
    nan.set_value(3, 30, 5, std::numeric_limits<double>::quiet_NaN());
    for (auto k :
         {IntegratorKind::alpha, IntegratorKind::preintegrated, IntegratorKind::preintegrated_simple})
        EXPECT_EQ(compare(nan, shell_tf(-1.5, 2.5), packet_settings(k, Model::emission_absorption), cams), 0)
            << to_string(k);
}

// Shaded with on-the-fly gradients, the point rules' packets shade each
// lane at its own sample, under its own ray's view, and pre-integration's
// each packed segment at its midpoint: the same bits as the batch's
// shading ray by ray, under a head light, two coloured lights with a
// highlight (squarings, and libm's pow for a shininess of 12.5), with
// gradient opacity (also alone, under absorption and emission), at
// midpoints, on a sheared lattice and on every target; and where optical
// depths beyond the exponential's range leave segments to the scalar code.
TEST(Packets, ShadedFramesAreBitIdentical) {
    const auto targets = simd::available_targets();
    ASSERT_FALSE(targets.empty());
    int compared = 0;
    for (const Range& r : {kTypes[0], kTypes[3], kTypes[6]}) {
        Volume v = shells(r.type, r.lo, r.hi);
        if (r.type == DType::i16) {  // the chain rule's matrix not symmetric
            const double a = 0.4;
            v.set_axes(Mat3::from_columns({1.2 * std::cos(a), 1.2 * std::sin(a), 0},
                                          {-std::sin(a), std::cos(a), 0.3}, {0.1, 0, 0.9}));
        }
        const auto cams = test::comparison_cameras(v);
        const double range = r.hi - r.lo;
        for (int light = 0; light < 4; ++light)  // head light; two lights; gradient opacity alone (2 models)
            for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated,
                           IntegratorKind::preintegrated_simple})
                for (auto t : targets) {
                    simd::force_target(t);
                    const Model m = light == 2   ? Model::absorption
                                    : light == 3 ? Model::emission
                                                 : Model::emission_absorption;
                    RenderSettings s = packet_settings(k, m);
                    TransferFunction tf = shell_tf(r.lo, r.hi);
                    s.shading.enabled = light < 2;
                    if (light == 1) {
                        s.shading.lights = {{{1, 0.5, -0.2}, {1, 0.8, 0.6}}, {{-0.3, 1, 0.4}, {0.2, 0.4, 1}}};
                        s.shading.specular = 0.5;
                        s.shading.shininess = r.type == DType::f32 ? 12.5 : 13;
                        s.sample_point = SamplePoint::mid;
                    }
                    if (light >= 1)
                        tf.gradient_opacity_points = {{0, 1}, {0.1 * range, 0.2}, {0.4 * range, 1}};
                    EXPECT_EQ(compare(v, tf, s, cams), 0)
                        << simd::active_target() << " " << dtype_name(r.type) << " " << to_string(k)
                        << " case " << light;
                    ++compared;
                }
        simd::force_target(0);
    }
    EXPECT_EQ(compared, 3 * 4 * 4 * static_cast<int>(targets.size()));
    const Volume v = shells(DType::f32, -1.5, 2.5);
    for (auto k :
         {IntegratorKind::alpha, IntegratorKind::preintegrated, IntegratorKind::preintegrated_simple}) {
        RenderSettings s = packet_settings(k, Model::emission_absorption);
        s.shading.enabled = true;
        TransferFunction tf = shell_tf(-1.5, 2.5, false, 1e3);
        tf.gradient_opacity_points = {{0, 1}, {0.4, 0.2}, {1.6, 1}};
        EXPECT_EQ(compare(v, tf, s, test::comparison_cameras(v)), 0) << to_string(k) << " beyond the range";
    }
}

// Jittered (an offset per pixel), each packet ray samples and walks at its
// own offset, set up one ray at a time: the same bits as the one-by-one
// path, with and without skipping, shaded too; pre-integration ignores the
// jitter on both paths.
TEST(Packets, JitteredFramesAreBitIdentical) {
    int compared = 0;
    for (const Range& r : {kTypes[0], kTypes[3]}) {
        const Volume v = shells(r.type, r.lo, r.hi);
        const auto cams = test::comparison_cameras(v);
        for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated})
            for (int variant = 0; variant < 3; ++variant) {  // plain; no skipping; shaded
                RenderSettings s = packet_settings(k, Model::emission_absorption);
                s.jitter = true;
                s.jitter_seed = 7u + static_cast<std::uint32_t>(variant);
                s.skip_empty = variant != 1;
                s.shading.enabled = variant == 2;
                EXPECT_EQ(compare(v, shell_tf(r.lo, r.hi), s, cams), 0)
                    << dtype_name(r.type) << " " << to_string(k) << " variant " << variant;
                ++compared;
            }
    }
    EXPECT_EQ(compared, 2 * 3 * 3);
}

// With depth outputs, each point-sampled packet lane keeps its ray's
// DepthTrack sums (Σ T·α·t at the segments' midpoints, the first segment
// with α > 0): the same depth and first-hit maps, bit for bit, as the
// one-by-one path, shaded or not, with early termination or without.
TEST(Packets, DepthOutputsAreBitIdentical) {
    auto same_depths = [](const Image& a, const Image& b) {
        return a.depth.size() == b.depth.size() && !a.depth.empty() &&
               std::memcmp(a.depth.data(), b.depth.data(), sizeof(float) * a.depth.size()) == 0 &&
               std::memcmp(a.first_hit.data(), b.first_hit.data(), sizeof(float) * a.first_hit.size()) == 0;
    };
    int compared = 0, hits = 0;
    for (const Range& r : {kTypes[0], kTypes[3], kTypes[6]}) {
        const Volume v = shells(r.type, r.lo, r.hi);
        const auto cams = test::comparison_cameras(v);
        for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated,
                       IntegratorKind::preintegrated_simple})
            for (int variant = 0; variant < 3; ++variant) {  // plain; shaded; no termination (midpoints)
                RenderSettings s = packet_settings(k, Model::emission_absorption);
                s.depth_outputs = true;
                s.shading.enabled = variant == 1;
                if (variant == 2) {
                    s.termination = 0;
                    if (k == IntegratorKind::alpha || k == IntegratorKind::riemann)
                        s.sample_point = SamplePoint::mid;
                }
                EXPECT_EQ(compare(v, shell_tf(r.lo, r.hi), s, cams), 0)
                    << dtype_name(r.type) << " " << to_string(k);
                s.packets = false;
                const Renderer one_by_one(v, shell_tf(r.lo, r.hi), s);
                s.packets = true;
                const Renderer packets(v, shell_tf(r.lo, r.hi), s);
                for (const Camera& cam : cams) {
                    const Image a = packets.render(cam), b = one_by_one.render(cam);
                    EXPECT_TRUE(same_depths(a, b))
                        << dtype_name(r.type) << " " << to_string(k) << " " << variant;
                    for (float f : b.first_hit) hits += std::isfinite(f) ? 1 : 0;
                    ++compared;
                }
            }
    }
    EXPECT_EQ(compared, 3 * 4 * 3 * 4);
    EXPECT_GT(hits, 1000);  // the maps hold hits, not only +inf
}

// A renderer that takes its volume over samples bricks: packets read them
// through the same gathers (64 cells along x and y: two bricks each, a
// quarter more bytes at most).
TEST(Packets, BrickedVolumesAreBitIdentical) {
    for (const Range& r : {kTypes[0], kTypes[3]})
        for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated}) {
            const Volume v = shells(r.type, r.lo, r.hi, {65, 65, 33});
            const auto cams = test::comparison_cameras(v);
            RenderSettings s = packet_settings(k, Model::emission_absorption);
            s.brick_min_bytes = 0;
            s.packets = false;
            const Renderer one_by_one(Volume(v), shell_tf(r.lo, r.hi), s);
            s.packets = true;
            const Renderer packets(Volume(v), shell_tf(r.lo, r.hi), s);
            ASSERT_TRUE(packets.bricked());
            ASSERT_TRUE(packets.packets());
            for (const Camera& cam : cams)
                EXPECT_TRUE(same_pixels(packets.render(cam), one_by_one.render(cam)))
                    << dtype_name(r.type) << " " << to_string(k);
        }
}

// The bundled chest CT under the bone and soft-tissue presets, the frames
// the benchmarks time, at a small size.
TEST(Packets, ChestCtFramesAreBitIdentical) {
    const Volume v = read_nrrd(test::source_dir() / "data" / "lidc2.nrrd");
    const Bounds b = volume_bounds(v);
    const std::vector<Camera> cams{Camera::orbit(90, 10, 2.6, b.center, b.radius),
                                   Camera::orbit(30, 20, 2.4, b.center, b.radius)};
    for (const char* preset : {"ct-bone", "ct-soft-tissue"})
        for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated}) {
            RenderSettings s = packet_settings(k, Model::emission_absorption);
            s.width = s.height = 96;
            s.step = 0.5;
            EXPECT_EQ(compare(v, TransferFunction::preset(preset, v.value_range()), s, cams), 0)
                << preset << " " << to_string(k);
        }
}

// The rays' spans and walks come a vector at a time
// (simd::prepare_packet_rays) without cutting, one at a time with a
// cropping box or clipping planes: both the same bits as tracing the rays
// one by one, for cameras inside the volume, along its axes (direction
// components exactly 0 for the middle pixel row and column) and
// orthographic ones that miss it in part.
TEST(Packets, RaySetUpWithAndWithoutCuttingIsBitIdentical) {
    const Volume v = shells(DType::i16, -2000, 3000);
    const Bounds b = volume_bounds(v);
    std::vector<Camera> cams = test::comparison_cameras(v);
    cams.push_back(Camera::orbit(20, 15, 0.3, b.center, b.radius));  // inside
    cams.push_back(Camera::orbit(180, 0, 0.9, b.center, b.radius));  // inside, along an axis
    Camera ortho = Camera::orbit(90, 0, 3, b.center, b.radius);
    ortho.projection = Projection::orthographic;
    ortho.height = 3 * b.radius;  // wider than the volume: rays that miss it
    cams.push_back(ortho);
    for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated}) {
        RenderSettings s = packet_settings(k, Model::emission_absorption);
        s.width = 33;  // odd: a middle column and row of pixels
        s.height = 31;
        EXPECT_EQ(compare(v, shell_tf(-2000, 3000), s, cams), 0) << to_string(k) << " uncut";
        RenderSettings crop = s;
        crop.crop = WorldBox{b.center - Vec3{9, 8, 20}, b.center + Vec3{12, 30, 7}};
        EXPECT_EQ(compare(v, shell_tf(-2000, 3000), crop, cams), 0) << to_string(k) << " cropped";
        RenderSettings clip = s;
        clip.clip_planes = {{b.center, {0.3, -1, 0.2}}, {b.center + Vec3{5, 0, 0}, {-1, 0, 0}}};
        EXPECT_EQ(compare(v, shell_tf(-2000, 3000), clip, cams), 0) << to_string(k) << " clipped";
    }
}

// A lane's empty run ends a hair short of its box's computed exit, without
// the exit sample's check, where the ray crosses every axis it crosses at a
// step of at least a thousandth of a node; grazing rays (an axis crossed at
// a step far below that) keep the check. Both ways the images are the bits
// of the one-by-one walk, which checks every exit: oblique views, views
// along the axes and a hair off them, fine and coarse steps.
TEST(Packets, EmptyRunsEndingShortOfTheirExitsAreBitIdentical) {
    const Volume v = shells(DType::u8, 0, 250, {47, 39, 44});
    const Bounds b = volume_bounds(v);
    std::vector<Camera> cams;
    for (double az : {0.0, 1e-7, 17.0, 45.0, 90.0 - 1e-7, 135.0})
        for (double el : {0.0, 1e-7, 33.0, -61.0})
            cams.push_back(Camera::orbit(az, el, 2.3, b.center, b.radius));
    for (auto k : {IntegratorKind::alpha, IntegratorKind::riemann, IntegratorKind::preintegrated})
        for (double step : {0.31, 1.1}) {
            RenderSettings s = packet_settings(k, Model::emission_absorption);
            s.step = step;
            EXPECT_EQ(compare(v, shell_tf(0, 250), s, cams), 0) << to_string(k) << " step " << step;
        }
}

// Renderer::render into a kept image (a viewer's frames): the pixels are
// not cleared, so every path must write every one. Images filled with NaN
// first, then rendered into again and again, against fresh ones: the same
// bits, with and without packets, skipping, depth outputs and cropping (rays
// that miss), and an image of another size replaced.
TEST(Frames, AKeptImageGetsEveryPixelOfAFreshOne) {
    const Volume v = shells(DType::u8, 0, 250);
    const TransferFunction tf = shell_tf(0, 250);
    const Bounds b = volume_bounds(v);
    const std::vector<Camera> cams{Camera::orbit(30, 20, 2.0, b.center, b.radius),
                                   Camera::orbit(100, -40, 1.2, b.center, b.radius)};
    auto nan_image = [](int w, int h) {
        Image img(w, h);
        std::fill(img.rgba.begin(), img.rgba.end(), std::numeric_limits<float>::quiet_NaN());
        return img;
    };
    int checked = 0;
    for (auto k : {IntegratorKind::alpha, IntegratorKind::preintegrated, IntegratorKind::reference})
        for (int variant = 0; variant < 4; ++variant) {
            RenderSettings s = packet_settings(k, Model::emission_absorption);
            s.packets = variant != 1;
            s.skip_empty = variant != 2;
            s.depth_outputs = variant == 3;
            if (variant == 2) s.crop = WorldBox{b.center - Vec3{5, 5, 5}, b.center + Vec3{8, 6, 9}};
            const Renderer r(v, tf, s);
            Image kept = nan_image(s.width, s.height);
            Image other = nan_image(s.width + 3, s.height);
            for (const Camera& cam : cams) {
                const Image fresh = r.render(cam);
                r.render(cam, kept);
                r.render(cam, other);
                for (const Image* img : {&kept, &other}) {
                    EXPECT_TRUE(same_pixels(*img, fresh)) << to_string(k) << " variant " << variant;
                    ASSERT_EQ(img->depth.size(), fresh.depth.size());
                    if (!fresh.depth.empty()) {  // (memcmp takes no null pointers)
                        EXPECT_EQ(std::memcmp(img->depth.data(), fresh.depth.data(), 4 * fresh.depth.size()),
                                  0);
                    }
                }
                ++checked;
            }
        }
    EXPECT_EQ(checked, 24);
}
