// The renderer's state and the per-frame tracer factories, shared by
// renderer.cpp and the tracer translation units (tracers_*.cpp), which
// instantiate the ray integrals per sample type in parallel builds.
#pragma once

#include <algorithm>
#include <cmath>
#include <functional>
#include <memory>
#include <mutex>
#include <vector>

#include "fathom/error.h"
#include "fathom/render.h"

#include "integrate/point_sampled.h"
#include "integrate/ray_span.h"
#include "render/empty_space.h"
#include "render/shading.h"
#include "volume/bricks.h"

namespace fathom {

using Tracer = std::function<RayResult(const RaySpan&)>;

/// A render thread's buffers for the ray packets of its tiles.
struct TilePackets {
    // the camera rays of a tile that has no crop or clipping planes, for
    // simd::prepare_packet_rays
    std::vector<double> in[8];  // origin, direction (3 each), bounds lo, hi
    std::vector<std::array<int, 2>> in_pixels;
    std::vector<simd::PacketRay> prepared;
    std::vector<int> prepared_octants;
    std::vector<std::uint8_t> meets;
    std::vector<simd::PacketRay> rays;
    std::vector<simd::PacketResult> results;
    std::vector<std::array<int, 2>> pixels;
    std::vector<int> octants;
    std::vector<std::size_t> order;  // by octant, where they differ
    std::vector<simd::PacketRay> grouped;
};

struct Renderer::Impl {
    RenderSettings s;
    std::array<std::int64_t, 3> dims{0, 0, 0};  // the lattice rays cross
    Mat3 axes;                                  // and its placement (index → world)
    Classifier tf;
    Mat3 world_to_index;
    Vec3 origin;
    double h = 0;  // step in world units
    Rgb bg{};
    EmptySpace empty_space;
    MacrocellRanges ranges;         // mip, minip and isosurfaces
    MacrocellRanges coarse_ranges;  // minip: ranges.coarser(kCoarseLevels)
    double empty_value = 0.0;       // the projections' empty macrocells' value (EmptySpace::for_value)
    simd::FlatFunction flat_sigma, flat_color;
    simd::BreakTable break_table;
    simd::BatchSource batch;                  // batch.data == nullptr: no SIMD
    std::vector<std::uint32_t> active_cells;  // batch.active
    Volume owned;   // the volume, where the renderer took it over (emptied once in bricks)
    Bricks bricks;  // its samples in bricks, where they pay (batch.data then points here)
    ShadeSetup shade;
    Volume gradients;  // precomputed node gradients (GradientSource::precomputed)
    Tracer tracer;
    /// The frame's rays go through simd::trace_packets (RenderSettings::packets):
    /// where the tracer is the point-sampled or pre-integrated SIMD walk it
    /// repeats (shaded with on-the-fly gradients or not).
    bool packets = false;
    /// With packets, pre-integrated (packet_preint; else point-sampled).
    bool packet_preint_on = false;
    simd::PacketPreint packet_preint;

    /// Renderer(volume, tf, settings); `own`: volume is `owned`, which may
    /// go into bricks.
    void setup_scalar(const Volume& volume, const TransferFunction& transfer, RenderSettings settings,
                      bool own);

    /// The macrocells to skip, or nullptr when skipping is off or useless.
    [[nodiscard]] const EmptySpace* skipper() const {
        return s.skip_empty && empty_space.any() ? &empty_space : nullptr;
    }

    /// The SIMD batches' source, or nullptr without SIMD.
    [[nodiscard]] const simd::BatchSource* simd_source() const {
        return batch.data != nullptr ? &batch : nullptr;
    }

    /// The macrocell ranges to skip by, or nullptr when skipping is off.
    [[nodiscard]] const MacrocellRanges* ranger() const {
        return s.skip_empty && ranges.dims()[0] > 0 ? &ranges : nullptr;
    }

    /// The ray's span inside the volume, cropped and clipped; false when
    /// nothing of it is left. t is the world distance along the ray in both
    /// spaces (dp = M⁻¹·d with |d| = 1).
    [[nodiscard]] bool span_of(const Ray& ray, RaySpan& span) const {
        const Vec3 p0 = world_to_index * (ray.origin - origin);
        const Vec3 dp = world_to_index * ray.dir;
        if (!intersect_box(p0, dp, dims, span)) return false;
        if (!s.crop && s.clip_planes.empty()) return true;
        double t0 = span.t_near, t1 = span.t_far;
        if (s.crop) {
            for (int a = 0; a < 3; ++a) {
                const double o = ray.origin[a], d = ray.dir[a], lo = s.crop->min[a], hi = s.crop->max[a];
                if (d == 0.0) {
                    if (o < lo || o > hi) return false;
                    continue;
                }
                double ta = (lo - o) / d, tb = (hi - o) / d;
                if (ta > tb) std::swap(ta, tb);
                t0 = std::max(t0, ta);
                t1 = std::min(t1, tb);
            }
        }
        for (const ClipPlane& pl : s.clip_planes) {  // keep n·(x(t) − p) = a + b·t ≥ 0
            const double a = dot(pl.normal, ray.origin - pl.point), b = dot(pl.normal, ray.dir);
            if (b == 0.0) {
                if (a < 0.0) return false;
            } else if (b > 0.0) {
                t0 = std::max(t0, -a / b);
            } else {
                t1 = std::min(t1, -a / b);
            }
        }
        if (!(t1 > t0)) return false;
        span.t_near = t0;
        span.t_far = t1;
        return true;
    }

    /// The `count` rays of one tile (pixel(q), q < count) through
    /// simd::trace_packets, a call per octant the rays travel in (a tile
    /// across an axis's turning has several); write(x, y, result) takes
    /// each pixel's result.
    template <class Pixel, class Rays, class Write>
    void trace_packets(TilePackets& tp, int count, Pixel&& pixel, const Rays& rays, const PixelBounds& bounds,
                       bool empty_is_background, Write&& write) const {
        tp.rays.clear();
        tp.pixels.clear();
        tp.octants.clear();
        const EmptySpace& es = empty_space;  // the skipper's, or none empty (setup_scalar)
        bool mixed = false;
        auto add = [&](const simd::PacketRay& r, std::array<int, 2> xy, int o) {
            mixed = mixed || (!tp.octants.empty() && o != tp.octants.front());
            tp.rays.push_back(r);
            tp.pixels.push_back(xy);
            tp.octants.push_back(o);
        };
        // pre-integration's ends lie at the segments' near ends (jitter or
        // not, as integrate_preintegrated's); point samples where the
        // sample_point setting puts them, or each pixel's jitter
        const double offset = packet_preint_on ? 0.0 : point_offset(s.sample_point);
        const bool jittered = s.jitter && !packet_preint_on;
        // Without cutting, the rays' spans and walks come a vector at a time
        // after this loop; with a cropping box or clipping planes, or
        // jittered (an offset per ray), one at a time.
        const bool cut = s.crop || !s.clip_planes.empty() || jittered;
        // (sized once per tile and filled by index: no push_back per ray)
        const auto slots = static_cast<std::size_t>(count);
        for (auto& v : tp.in) v.resize(slots);
        tp.in_pixels.resize(slots);
        std::size_t k_in = 0;
        for (int q = 0; q < count; ++q) {
            const auto [x, y] = pixel(q);
            double lo = 0, hi = 0;
            bounds.at(x, y, lo, hi);
            if (!(lo <= hi)) {
                write(x, y, empty_is_background ? RayResult{bg, 0.0} : trace(rays(x, y), -1.0, lo, hi));
                continue;
            }
            const Ray ray = rays(x, y);
            if (!cut) {
                for (int a = 0; a < 3; ++a) {
                    tp.in[a][k_in] = ray.origin[a];
                    tp.in[3 + a][k_in] = ray.dir[a];
                }
                tp.in[6][k_in] = lo;
                tp.in[7][k_in] = hi;
                tp.in_pixels[k_in] = {x, y};
                ++k_in;
                continue;
            }
            RaySpan span;
            if (!span_of(ray, span)) {
                write(x, y, RayResult{bg, 0.0});
                continue;
            }
            span.occupied_lo = lo;
            span.occupied_hi = hi;
            // integrate_point_sampled's grid and walk
            const std::int64_t n = segment_count(span.length(), h);
            simd::PacketRay r{};
            r.delta = span.length() / static_cast<double>(n);
            r.offset = jittered ? point_offset(s.sample_point, jitter_offset(x, y, s.jitter_seed)) : offset;
            r.t_near = span.t_near;
            r.n = static_cast<double>(n);
            for (int a = 0; a < 3; ++a) {
                r.p0[a] = span.p0[a];
                r.dp[a] = span.dp[a];
            }
            int o = 0;
            RunFinder(es, SampleGrid{&span, r.delta, r.offset, 1})
                .forward_walk(o, r.A, r.B, r.before, r.after);
            add(r, {x, y}, o);
        }
        if (const std::size_t k = k_in; k > 0) {
            simd::PacketFrame f;
            for (int a = 0; a < 3; ++a) {
                for (int b = 0; b < 3; ++b) f.world_to_index[a][b] = world_to_index.m[a][b];
                f.origin[a] = origin[a];
                f.node_hi[a] = static_cast<double>(dims[a] - 1);
            }
            f.h = h;
            f.offset = offset;
            const simd::PacketRaysIn in{{tp.in[0].data(), tp.in[1].data(), tp.in[2].data()},
                                        {tp.in[3].data(), tp.in[4].data(), tp.in[5].data()},
                                        tp.in[6].data(),
                                        tp.in[7].data(),
                                        k};
            tp.prepared.resize(k);
            tp.prepared_octants.resize(k);
            tp.meets.resize(k);
            simd::prepare_packet_rays(f, in, tp.prepared.data(), tp.prepared_octants.data(), tp.meets.data());
            for (std::size_t i = 0; i < k; ++i) {
                if (tp.meets[i] != 0)
                    add(tp.prepared[i], tp.in_pixels[i], tp.prepared_octants[i]);
                else  // span_of: no span
                    write(tp.in_pixels[i][0], tp.in_pixels[i][1], RayResult{bg, 0.0});
            }
        }
        if (tp.rays.empty()) return;
        simd::PacketWalk w;
        w.empty = es.empty_bytes();
        w.cells = es.dims()[0] * es.dims()[1] * es.dims()[2];
        for (int a = 0; a < 3; ++a) {
            w.dims[a] = static_cast<double>(es.dims()[a]);
            w.nodes[a] = static_cast<double>(es.nodes()[a]);
        }
        w.shift = es.shift();
        auto trace_group = [&](const simd::PacketRay* group, std::size_t count, int octant,
                               simd::PacketResult* out) {
            w.octant = octant;
            w.ahead = es.ahead(octant);
            unsigned axes = 0;  // the rays' main axes: the along() rows they read
            for (std::size_t k = 0; k < count; ++k) axes |= 1u << simd::packet_main_axis(group[k].dp);
            w.along = es.along(octant, axes);
            simd::trace_packets(batch, w, group, count, s.termination, bg.data(), out,
                                packet_preint_on ? &packet_preint : nullptr, s.depth_outputs);
        };
        auto result_of = [&](const simd::PacketResult& pr) {
            RayResult r{{pr.radiance[0], pr.radiance[1], pr.radiance[2]}, pr.alpha};
            if (s.depth_outputs) {
                r.depth = pr.depth;
                r.first_hit = pr.first_hit;
            }
            return r;
        };
        tp.results.resize(tp.rays.size());
        const std::size_t count_traced = tp.rays.size();
        if (!mixed) {
            trace_group(tp.rays.data(), count_traced, tp.octants.front(), tp.results.data());
            for (std::size_t k = 0; k < count_traced; ++k) {
                const simd::PacketResult& pr = tp.results[k];
                write(tp.pixels[k][0], tp.pixels[k][1], result_of(pr));
            }
            return;
        }
        // a tile across an axis's turning: the rays of each octant together
        tp.order.resize(count_traced);
        for (std::size_t k = 0; k < count_traced; ++k) tp.order[k] = k;
        std::stable_sort(tp.order.begin(), tp.order.end(),
                         [&](std::size_t a, std::size_t b) { return tp.octants[a] < tp.octants[b]; });
        tp.grouped.resize(count_traced);
        for (std::size_t k = 0; k < count_traced; ++k) tp.grouped[k] = tp.rays[tp.order[k]];
        for (std::size_t k0 = 0; k0 < count_traced;) {
            std::size_t k1 = k0;
            while (k1 < count_traced && tp.octants[tp.order[k1]] == tp.octants[tp.order[k0]]) ++k1;
            trace_group(tp.grouped.data() + k0, k1 - k0, tp.octants[tp.order[k0]], tp.results.data() + k0);
            k0 = k1;
        }
        for (std::size_t k = 0; k < count_traced; ++k) {
            const simd::PacketResult& pr = tp.results[k];
            const auto [x, y] = tp.pixels[tp.order[k]];
            write(x, y, result_of(pr));
        }
    }

    /// The frame's PixelBounds for `camera` where its tracer walks the
    /// macrocells (the integrators over segments of a zero-able medium,
    /// isosurfaces and the average); else none.
    void pixel_bounds(const Camera& camera, PixelBounds& out) const;
    /// A frame's bounds storage: the last frame's, kept (a frame at a time
    /// reuses its pages), or new where another frame holds it.
    [[nodiscard]] std::unique_ptr<PixelBounds> take_bounds() const {
        const std::lock_guard lock(bounds_mutex);
        return kept_bounds != nullptr ? std::move(kept_bounds) : std::make_unique<PixelBounds>();
    }
    void keep_bounds(std::unique_ptr<PixelBounds> b) const {
        const std::lock_guard lock(bounds_mutex);
        if (kept_bounds == nullptr) kept_bounds = std::move(b);
    }
    mutable std::mutex bounds_mutex;
    mutable std::unique_ptr<PixelBounds> kept_bounds;

    /// True where trace() gives the background, alpha 0, for every ray whose
    /// bounds hold no non-empty macrocell (occupied_lo > occupied_hi),
    /// whether or not it meets the volume: the model is not a projection
    /// (`average`, `mip`, `minip`), whose empty rays give tf.color(0), and
    /// no background component is −0 (which compositing turns into +0).
    /// Then the render loop need not make such a ray at all.
    [[nodiscard]] bool empty_rays_see_background() const {
        return !projection() &&
               std::none_of(bg.begin(), bg.end(), [](double c) { return c == 0.0 && std::signbit(c); });
    }

    /// The projections, whose macrocells are empty where their nodes are
    /// all `empty_value` (EmptySpace::for_value): a ray that meets no other gives
    /// c(empty_value) (c(−0) is c(0)'s bits: a piece's w of ±0 adds nothing).
    [[nodiscard]] bool projection() const {
        return s.model == Model::average || s.model == Model::mip || s.model == Model::minip;
    }

    /// The ray's result; [occupied_lo, occupied_hi] bounds the t of its
    /// points near non-empty macrocells (RaySpan).
    [[nodiscard]] RayResult trace(const Ray& ray, double sample_offset = -1.0, double occupied_lo = -INFINITY,
                                  double occupied_hi = INFINITY) const {
        RaySpan span;
        if (!span_of(ray, span)) return {bg, 0.0};
        if (!(occupied_lo <= occupied_hi)) {  // no sample can be in a non-empty macrocell
            if (projection()) return {tf.color(empty_value), 1.0};  // every sample `empty_value` (or ±0)
            const auto nothing = [](std::int64_t) { return Segment{1.0, {}}; };  // every segment (1, 0)
            return composite(0, s.order, s.termination, bg, nothing);
        }
        span.sample_offset = sample_offset;
        span.occupied_lo = occupied_lo;
        span.occupied_hi = occupied_hi;
        return tracer(span);
    }
};

/// Throws Error(what) unless every dimension has at least 2 samples.
void check_lattice(const Volume& v, const std::string& what);
/// Validates the settings and sets the lattice, its transform, the step in
/// world units and the background.
void setup_lattice(Renderer::Impl& im, const Volume& lattice);

/// The tracer of a scalar volume of sample type T (gradient_work: lighting
/// and/or gradient opacity, im.shade says which).
template <class T>
Tracer scalar_tracer(const Volume& volume, const Renderer::Impl& im, bool gradient_work);
/// The tracer of pre-classified density (D) and color (C) grids.
template <class D, class C>
Tracer grid_tracer(const Volume& density, const Volume& color, const Renderer::Impl& im);

}  // namespace fathom
