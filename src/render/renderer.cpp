// The renderer: chooses one template instantiation of the ray integral per
// frame (medium type × model × integrator), then runs tiles over threads.
#include <algorithm>
#include <atomic>
#include <exception>
#include <mutex>
#include <vector>

#include "fathom/error.h"
#include "fathom/log.h"
#include "fathom/render.h"

#include "core/parallel.h"
#include "integrate/preintegrated.h"
#include "render/empty_space.h"
#include "render/renderer_impl.h"

namespace fathom {

double jitter_offset(int x, int y, std::uint32_t seed) {
    std::uint32_t h = static_cast<std::uint32_t>(x) * 0x9E3779B1u ^
                      static_cast<std::uint32_t>(y) * 0x85EBCA77u ^ seed * 0xC2B2AE3Du;
    h ^= h >> 16;
    h *= 0x7FEB352Du;
    h ^= h >> 15;
    h *= 0x846CA68Bu;
    h ^= h >> 16;
    return static_cast<double>(h) / 4294967296.0;
}

void check_lattice(const Volume& v, const std::string& what) {
    for (auto d : v.dims())
        if (d < 2) throw Error(what, "every dimension must be at least 2 samples to interpolate");
}

namespace {

/// Macrocell edge (log2 cells): 4³ by default. Finer macrocells skip more
/// samples; with the boxes ahead a ray crosses regions of many of them in
/// one step, so 4³ beats 8³ for the pre-integrated integrators too
/// (docs/performance.md).
constexpr int kMacrocellShift = 2;

/// The optical models and isosurfaces skip by 2³ macrocells where the
/// lattice has at most s.fine_macrocells_max of them and at least this share
/// of the 2×2×2 groups of them that hold a non-empty one is empty
/// (EmptySpace::empty_share_in_pairs: what 4³ macrocells would evaluate and
/// 2³ skip), else by 4³. Frames with 2³ measured 1.05–1.23× at shares of
/// 0.29–0.51, the same at 0.24, and 0.94–0.96× at 0.09 (docs/performance.md,
/// "Empty-space skipping"). The average and pre-classified grids keep 4³
/// (2³ was 0.7–0.9× for the average).
constexpr double kFineShareWorth = 0.25;

/// simd::PacketPreint::scalar: integrate_preintegrated's scalar segment
/// (ctx: the renderer's Impl).
void preint_scalar_segment(const void* ctx, double vf, double vb, double delta, double* t, double* radiance) {
    const auto& im = *static_cast<const Renderer::Impl*>(ctx);
    const bool full = im.s.integrator == IntegratorKind::preintegrated;
    const Segment seg = im.s.model == Model::emission
                            ? preintegrate_scalar<Model::emission>(im.tf, vf, vb, delta, full)
                        : im.s.model == Model::absorption
                            ? preintegrate_scalar<Model::absorption>(im.tf, vf, vb, delta, full)
                            : preintegrate_scalar<Model::emission_absorption>(im.tf, vf, vb, delta, full);
    *t = seg.transmittance;
    for (int k = 0; k < 3; ++k) radiance[k] = seg.radiance[k];
}

template <class Classify>
EmptySpace skipping_macrocells(const Volume& v, const RenderSettings& s, Classify&& classify) {
    const auto fine = MacrocellLattice::dims_of(v.dims(), 1);
    if (static_cast<std::uint64_t>(fine[0] * fine[1] * fine[2]) <= s.fine_macrocells_max) {
        EmptySpace es = classify(1);
        if (es.empty_share_in_pairs() >= kFineShareWorth) return es;
        if (es.joins_empty()) return es.coarser();  // the same as classifying 4³, from the grid
    }
    return classify(kMacrocellShift);
}

/// Macrocell edge (log2 cells) of the ranges that mip, minip and
/// isosurfaces skip by: 4³ bounds a batch of 16 ends more tightly than 8³
/// (mip 6–15 % faster; isosurfaces and minip −5 to +15 %; a float pair per
/// macrocell, 12 MB on the bunny; docs/performance.md, "Projections and
/// isosurfaces").
constexpr int kRangeShift = 2;
/// MinIP's coarse ranges (project's groups): macrocells 2^kCoarseLevels
/// times the ranges' edge. MIP does without: a CT's maxima lie in thin
/// bone, whose coarse macrocells' highs stand above most rays' maxima, so
/// most groups would be split (docs/performance.md, "Projections and
/// isosurfaces").
constexpr int kCoarseLevels = 2;

/// The least share of inactive blocks inside non-empty macrocells at which
/// the inactive-block bits pay (docs/performance.md, "Blocks in the
/// medium's zero range": measured on real volumes at shares of 0.01–0.43).
constexpr double kInactiveShareWorth = 0.15;

/// The least share of macrocells of zeros at which the average's walk past
/// them pays (docs/performance.md, "Projections and isosurfaces": the
/// bunny, 0.03 % of its macrocells, was 3–6 % slower with it).
constexpr double kZerosWorth = 0.05;

/// How far a step along v (index space) moves across the volume's rows.
double row_drift(const Vec3& v) {
    return std::hypot(v.y, v.z);
}

}  // namespace

void setup_lattice(Renderer::Impl& im, const Volume& lattice) {
    im.s.validate();
    im.dims = lattice.dims();
    im.axes = lattice.axes();
    im.world_to_index = lattice.axes().inverse();
    im.origin = lattice.origin();
    im.h = im.s.step_world ? im.s.step : im.s.step * lattice.smallest_spacing();
    im.bg = im.s.background_radiance();
}

Renderer::Renderer(const Volume& volume, const TransferFunction& tf, RenderSettings settings)
    : impl_(std::make_unique<Impl>()) {
    impl_->setup_scalar(volume, tf, std::move(settings), false);
}

Renderer::Renderer(Volume&& volume, const TransferFunction& tf, RenderSettings settings)
    : impl_(std::make_unique<Impl>()) {
    impl_->owned = std::move(volume);
    impl_->setup_scalar(impl_->owned, tf, std::move(settings), true);
}

bool Renderer::bricked() const {
    return !impl_->bricks.empty();
}

bool Renderer::packets() const {
    return impl_->packets;
}

int Renderer::macrocell_cells() const {
    return impl_->empty_space.any() ? impl_->empty_space.edge() : 0;
}

void Renderer::Impl::setup_scalar(const Volume& volume, const TransferFunction& transfer,
                                  RenderSettings settings, bool own) {
    s = std::move(settings);
    check_lattice(volume, "volume");
    if (volume.components() != 1)
        throw Error("volume",
                    "a scalar volume needs 1 component, this one has " + std::to_string(volume.components()));
    setup_lattice(*this, volume);
    tf = Classifier(transfer, volume.smallest_spacing());
    // Macrocells empty by the iso-values, by one value (zeros, which add
    // nothing to the average; for mip and minip, which skip by ranges, a
    // value that a ray meeting nothing else projects: its pixel bounds),
    // or by the medium (the optical models): one classification per model.
    if (s.skip_empty && s.model == Model::isosurface) {
        std::vector<double> isos;
        for (const IsoSurface& iso : s.isosurfaces) isos.push_back(iso.value);
        empty_space = skipping_macrocells(volume, s, [&](int shift) {
            return EmptySpace::for_isosurfaces(volume, isos, shift, s.threads);
        });
    } else if (s.skip_empty &&
               (s.model == Model::average || s.model == Model::mip || s.model == Model::minip)) {
        // MIP's: the lowest value (a CT's padding outside the scanner's
        // field of view, or its air), which no ray's largest sample needs
        // where it meets anything else; the average's and MinIP's: 0
        // (their ranges, which skip the rest, built here: their pass over
        // the nodes finds the lowest)
        if (s.model == Model::mip || s.model == Model::minip) {
            ranges = MacrocellRanges(volume, kRangeShift, s.threads);
            if (s.model == Model::minip) coarse_ranges = ranges.coarser(kCoarseLevels);
        }
        if (s.model == Model::mip && std::isfinite(ranges.lowest_node())) empty_value = ranges.lowest_node();
        empty_space = EmptySpace::for_value(volume, empty_value, kMacrocellShift, s.threads);
        if (empty_space.empty_fraction() < kZerosWorth) empty_space = {};
    } else if (s.skip_empty) {
        empty_space = skipping_macrocells(volume, s, [&](int shift) {
            return EmptySpace::for_scalar(volume, tf, s.model, shift, s.threads);
        });
    }
    // Isosurfaces walk the macrocells where a step reaches a touching one at
    // most along each axis (trace_isosurfaces); the ranges serve larger
    // steps, and mip and minip.
    double index_step = 0;  // the most a step of h moves along an index axis
    for (int a = 0; a < 3; ++a)
        index_step = std::max(index_step, h * length(Vec3{world_to_index.m[a][0], world_to_index.m[a][1],
                                                          world_to_index.m[a][2]}));
    const bool iso_ranges = s.model == Model::isosurface && index_step > empty_space.touching_step();
    if (s.skip_empty && iso_ranges) ranges = MacrocellRanges(volume, kRangeShift, s.threads);
    if (s.simd) {
        flat_sigma = simd::flatten(tf.sigma_function());
        flat_color = simd::flatten(tf.color_function());
        batch = {volume.bytes(),   volume.dtype(), volume.dims()[0], volume.dims()[1],
                 volume.dims()[2], &flat_sigma,    &flat_color,      zero_below(tf, s.model)};
        batch.shared_knots = simd::same_knots(flat_sigma, flat_color);
        batch.breaks = &tf.breakpoints();
        break_table = simd::BreakTable(tf.breakpoints());
        batch.break_table = break_table.get();
        batch.integrals = &tf.integrals();
        batch.associated = tf.associated();
        const bool point_sampled = s.integrator == IntegratorKind::alpha ||
                                   s.integrator == IntegratorKind::riemann;  // classify_batch's users
        if (s.skip_empty && point_sampled && std::isfinite(batch.zero_below)) {
            active_cells = simd::active_cells(volume, batch.zero_below, s.threads);
            // The bits cost a gather per vector and pay where the vectors the
            // walk evaluates often lie wholly in inactive blocks: kept where
            // enough of the blocks inside the non-empty macrocells are.
            if (!active_cells.empty() && empty_space.inactive_share(active_cells) < kInactiveShareWorth)
                active_cells = {};
            if (!active_cells.empty()) batch.active = active_cells.data();
        }
    }
    const Shading& sh = s.shading;
    const Model model = s.model;
    const bool lit = sh.enabled && model == Model::emission_absorption;
    const bool optical =
        model == Model::emission_absorption || model == Model::absorption || model == Model::emission;
    const bool modulated = optical && tf.has_gradient_opacity();
    const bool gradient_work = lit || modulated;
    if (gradient_work || model == Model::isosurface) {  // isosurfaces are always lit
        shade = {sh.ambient, sh.diffuse, sh.specular, sh.shininess, {}, world_to_index, volume.axes()};
        for (Light l : sh.lights) {
            l.direction = l.direction * (1.0 / length(l.direction));
            shade.lights.push_back(l);
        }
        shade.light = lit || model == Model::isosurface;
        shade.modulate = modulated ? &tf : nullptr;
        if (gradient_work && s.gradient == GradientSource::precomputed) {
            const std::uint64_t bytes = static_cast<std::uint64_t>(volume.num_nodes()) * 3 * sizeof(float);
            if (bytes <= s.gradient_memory) {
                gradients = node_gradients(volume, world_to_index, s.threads);
                shade.gradients = &gradients;
            } else {
                warn("gradient volume of " + std::to_string(bytes >> 20) + " MiB exceeds the limit of " +
                     std::to_string(s.gradient_memory >> 20) + " MiB: gradients are computed on the fly");
            }
        }
    }
    // Point sampling: the classifier applies the segment rule too, and
    // shades with on-the-fly gradients.
    if (batch.data != nullptr && optical && (!gradient_work || shade.gradients == nullptr)) {
        if (gradient_work) batch.shade = &shade;
        batch.model = model;
        if (s.integrator == IntegratorKind::alpha) batch.rule = simd::PointRule::alpha;
        if (s.integrator == IntegratorKind::riemann) batch.rule = simd::PointRule::riemann;
    }
    // An owned volume in bricks where they pay: the unshaded SIMD path
    // (the only one that reads bricks) over a large volume of a paired type
    // whose bricks are not much larger (dimensions just past a multiple of
    // 32 cells would add a brick along each axis).
    const DType type = volume.dtype();
    const bool paired = visit_dtype(type, []<class T>(T*) { return simd::kPairs<T>; });
    const std::uint64_t brick_bytes = Bricks::bytes_for(volume);
    if (own && paired && batch.data != nullptr && optical && !gradient_work &&
        s.integrator != IntegratorKind::reference && volume.size_bytes() >= s.brick_min_bytes &&
        brick_bytes <= static_cast<std::uint64_t>(simd::kPairBytesMax) &&
        brick_bytes <= volume.size_bytes() / 4 * 5) {  // at most a quarter more bytes
        bricks = Bricks(owned, true, s.threads);
        owned = Volume();  // its pages went back as the bricks filled
        batch.data = bricks.bytes();
        batch.bricks_x = bricks.bricks_x();
        batch.bricks_y = bricks.bricks_y();
        batch.bricks_z = bricks.bricks_z();
    }
    // Ray packets repeat integrate_point_sampled's SIMD path with skipping
    // (front to back, shaded or not, jittered or not, with depth outputs or
    // not), and without:
    // where nothing is skipped (skipping off, or no macrocell empty) they
    // walk macrocells none of which is empty (EmptySpace::none), each ray's
    // span one run, as the one-by-one path's zero split takes it.
    const bool point = batch.rule != simd::PointRule::none;
    // So do integrate_preintegrated's SIMD windows (simd::PacketPreint)
    // where empty macrocells join, and where nothing is skipped (skipping
    // off, or no macrocell empty): every segment of a ray is then in its
    // one run.
    const bool preint =
        s.integrator == IntegratorKind::preintegrated || s.integrator == IntegratorKind::preintegrated_simple;
    const bool preint_packets = preint && optical && (skipper() == nullptr || empty_space.joins_empty());
    // Shaded, packets shade their samples (or segments) as the batch does
    // (on-the-fly gradients: batch.shade).
    // Depth outputs: packets keep each ray's depths.
    const bool eligible = s.packets && batch.data != nullptr && (point || preint_packets) &&
                          (!gradient_work || batch.shade != nullptr) && s.order == Order::front_to_back;
    if (eligible && skipper() == nullptr && empty_space.dims()[0] == 0)
        empty_space = EmptySpace::none(volume, kMacrocellShift);
    const auto& mc = empty_space.dims();
    packets = eligible && mc[0] * mc[1] * mc[2] >= 4;
    packet_preint_on = packets && preint_packets;
    packet_preint = {model, s.integrator == IntegratorKind::preintegrated, &preint_scalar_segment, this};
    // (Bricked, the tracer's scalar sampler holds no samples: nothing on
    // that path reads it.)
    tracer = visit_dtype(type, [&]<class T>(T*) {
        return scalar_tracer<T>(bricks.empty() ? volume : owned, *this, gradient_work);
    });
}

Renderer::Renderer(const Volume& density, const Volume& color, RenderSettings settings)
    : impl_(std::make_unique<Impl>()) {
    impl_->s = settings;
    check_lattice(density, "density grid");
    if (density.components() != 1) throw Error("density grid", "must have 1 component");
    if (color.components() != 3) throw Error("color grid", "must have 3 components (RGB)");
    if (density.dims() != color.dims())
        throw Error("color grid", "dimensions differ from the density grid's");
    auto is_float = [](DType t) { return t == DType::f32 || t == DType::f64; };
    if (!is_float(density.dtype()) || !is_float(color.dtype()))
        throw Error("pre-classified grids", "density and color must be float32 or float64");
    if (settings.shading.enabled)
        throw Error(
            "shading",
            "needs a scalar volume (its gradient gives the normals); pre-classified grids are not shaded");
    setup_lattice(*impl_, density);
    if (impl_->s.skip_empty)
        impl_->empty_space = EmptySpace::for_zeros(density, kMacrocellShift, impl_->s.threads);
    impl_->tracer = visit_dtype(density.dtype(), [&]<class D>(D*) -> Tracer {
        if constexpr (std::is_floating_point_v<D>) {
            return visit_dtype(color.dtype(), [&]<class C>(C*) -> Tracer {
                if constexpr (std::is_floating_point_v<C>) {
                    return grid_tracer<D, C>(density, color, *impl_);
                } else {
                    return {};
                }
            });
        } else {
            return {};
        }
    });
}

Renderer::~Renderer() = default;
Renderer::Renderer(Renderer&&) noexcept = default;
Renderer& Renderer::operator=(Renderer&&) noexcept = default;

const RenderSettings& Renderer::settings() const {
    return impl_->s;
}

void Renderer::Impl::pixel_bounds(const Camera& camera, PixelBounds& out) const {
    const bool segments = s.integrator == IntegratorKind::alpha || s.integrator == IntegratorKind::riemann ||
                          s.integrator == IntegratorKind::preintegrated ||
                          s.integrator == IntegratorKind::preintegrated_simple;
    const bool zero_able =
        s.model == Model::emission_absorption || s.model == Model::absorption || s.model == Model::emission;
    const EmptySpace* es = skipper();
    const bool walks = (segments && zero_able) || s.model == Model::isosurface || s.model == Model::average ||
                       s.model == Model::mip || s.model == Model::minip;
    if (es == nullptr || !walks) {
        out.clear();
        return;
    }
    es->pixel_bounds(out, camera, s.width, s.height, axes, origin, s.threads);
}

RayResult Renderer::trace(const Ray& ray) const {
    const EmptySpace::Use use(impl_->empty_space, false);
    return impl_->trace(ray);
}

Image Renderer::render(const Camera& camera, const ProgressFn& progress) const {
    Image img;
    render(camera, img, progress);
    return img;
}

void Renderer::render(const Camera& camera, Image& img, const ProgressFn& progress) const {
    const RenderSettings& s = impl_->s;
    // the macrocells' tables this frame reads stay; those the last frame
    // did not read go (EmptySpace::Use)
    const EmptySpace::Use use(impl_->empty_space, true);
    const std::size_t pixels = static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height);
    if (img.width != s.width || img.height != s.height || img.rgba.size() != 4 * pixels)
        img = Image(s.width, s.height);  // (a kept one is not cleared: every pixel is written below)
    if (s.depth_outputs) {
        img.depth.assign(pixels, INFINITY);
        img.first_hit.assign(pixels, INFINITY);
    } else {
        img.depth.clear();
        img.first_hit.clear();
    }
    std::unique_ptr<PixelBounds> held = impl_->take_bounds();
    impl_->pixel_bounds(camera, *held);
    const PixelBounds& bounds = *held;
    const bool empty_is_background = impl_->empty_rays_see_background();
    const PixelRays rays(camera, s.width, s.height);
    constexpr int kTile = 16;
    const int tx = (s.width + kTile - 1) / kTile, ty = (s.height + kTile - 1) / kTile;
    // A tile's rays in the order that keeps consecutive ones on the same rows
    // of the volume (x-fastest storage: a cache line runs along x), so they
    // share the lines they read: down the columns where a step along the
    // image's y moves less across the rows (y and z) than a step along its x.
    const bool by_columns =
        row_drift(impl_->world_to_index * camera.up) < row_drift(impl_->world_to_index * camera.right);
    const int tiles = tx * ty;
    std::atomic<int> next{0}, done{0};
    std::exception_ptr failure;
    std::mutex failure_mutex;
    auto write = [&](int x, int y, const RayResult& r) {
        float* p = img.pixel(x, y);
        for (int c = 0; c < 3; ++c) p[c] = static_cast<float>(r.radiance[c]);
        p[3] = static_cast<float>(r.alpha);
        if (s.depth_outputs) {
            const std::size_t k =
                static_cast<std::size_t>(y) * static_cast<std::size_t>(s.width) + static_cast<std::size_t>(x);
            img.depth[k] = static_cast<float>(r.depth);
            img.first_hit[k] = static_cast<float>(r.first_hit);
        }
    };
    auto worker = [&] {
        TilePackets packets;
        try {
            for (int t = next++; t < tiles; t = next++) {
                const int x0 = (t % tx) * kTile, y0 = (t / tx) * kTile;
                const int w = std::min(kTile, s.width - x0), h = std::min(kTile, s.height - y0);
                // q along the inner extent (a column's h pixels, or a row's
                // w), then across; a whole tile divides by the constant
                const int inner = by_columns ? h : w;
                auto pixel = [&](int q) {
                    const int across = inner == kTile ? q / kTile : q / inner, along = q - across * inner;
                    return by_columns ? std::array<int, 2>{x0 + across, y0 + along}
                                      : std::array<int, 2>{x0 + along, y0 + across};
                };
                if (impl_->packets) {
                    impl_->trace_packets(packets, w * h, pixel, rays, bounds, empty_is_background, write);
                } else {
                    for (int q = 0; q < w * h; ++q) {
                        const auto [x, y] = pixel(q);
                        const double offset = s.jitter ? jitter_offset(x, y, s.jitter_seed) : -1.0;
                        double lo = 0, hi = 0;
                        bounds.at(x, y, lo, hi);
                        write(x, y,
                              empty_is_background && !(lo <= hi) ? RayResult{impl_->bg, 0.0}
                                                                 : impl_->trace(rays(x, y), offset, lo, hi));
                    }
                }
                const int d = ++done;
                if (progress) progress(d, tiles);
            }
        } catch (...) {
            std::lock_guard lock(failure_mutex);
            if (!failure) failure = std::current_exception();
            next = tiles;
        }
    };
    run_parallel(std::min(resolve_threads(s.threads), tiles), [&](int) { worker(); });
    impl_->keep_bounds(std::move(held));
    if (failure) std::rethrow_exception(failure);
}

std::uint64_t Renderer::count_segments(const Camera& camera) const {
    const RenderSettings& s = impl_->s;
    const PixelRays rays(camera, s.width, s.height);
    std::uint64_t total = 0;
    for (int y = 0; y < s.height; ++y)
        for (int x = 0; x < s.width; ++x) {
            RaySpan span;
            if (impl_->span_of(rays(x, y), span))
                total += static_cast<std::uint64_t>(segment_count(span.length(), impl_->h));
        }
    return total;
}

Bounds volume_bounds(const Volume& v) {
    const Vec3 last{static_cast<double>(v.dims()[0] - 1), static_cast<double>(v.dims()[1] - 1),
                    static_cast<double>(v.dims()[2] - 1)};
    const Vec3 diag = v.axes() * last;
    return {v.origin() + diag * 0.5, 0.5 * length(diag)};
}

}  // namespace fathom
