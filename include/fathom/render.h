// Rendering: settings (SPEC §5, §7 "render"), the renderer over a scalar
// volume with a transfer function or over pre-classified σ/RGB grids, and
// single-ray tracing for tools and tests.
#pragma once

#include <cmath>
#include <cstdint>
#include <functional>
#include <memory>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fathom/camera.h"
#include "fathom/image.h"
#include "fathom/math.h"
#include "fathom/transfer_function.h"
#include "fathom/volume.h"

namespace fathom {

/// The optical models of SPEC §1, projection modes over the scalar (mip,
/// minip, average) and isosurfaces (the first crossings of iso-values,
/// shaded), which need a scalar volume.
enum class Model { emission_absorption, absorption, emission, mip, minip, average, isosurface };
enum class IntegratorKind { riemann, alpha, reference, preintegrated, preintegrated_simple };
enum class SamplePoint { near, mid };
enum class Order { front_to_back, back_to_front };

std::string_view to_string(Model m);
std::string_view to_string(IntegratorKind k);
std::string_view to_string(SamplePoint s);
std::string_view to_string(Order o);
/// Parsers for the names used in scene files and on the command line;
/// throw Error(subject, ...) listing the accepted names.
Model parse_model(std::string_view s, const std::string& subject);
IntegratorKind parse_integrator(std::string_view s, const std::string& subject);
SamplePoint parse_sample_point(std::string_view s, const std::string& subject);
Order parse_order(std::string_view s, const std::string& subject);

/// A clipping plane in world coordinates: keeps the points x with
/// normal·(x − point) ≥ 0 (the side the normal points to, as VTK's
/// clipping planes).
struct ClipPlane {
    Vec3 point;
    Vec3 normal;
};

/// An axis-aligned box in world coordinates.
struct WorldBox {
    Vec3 min, max;
};

/// A directional light; `direction` points from the scene toward the light
/// (world coordinates, any length > 0); `color` scales its contribution.
struct Light {
    Vec3 direction;
    Rgb color{1, 1, 1};
};

/// Blinn–Phong local illumination of the source term (docs/shading.md):
/// g' = g·(k_a + Σ k_d·|n·l|·L) + σ·Σ k_s·|n·h|^p·L, with n the normalised
/// gradient of the scalar (two-sided) and h the half vector; opacity is not
/// shaded. Defaults as VTK's volume property.
struct Shading {
    bool enabled = false;
    double ambient = 0.1, diffuse = 0.7, specular = 0.2, shininess = 10.0;
    /// Empty: one white head light (from the camera).
    std::vector<Light> lights;
};

/// Where shading and gradient opacity get the gradient ∇v from.
enum class GradientSource : std::uint8_t {
    /// Central differences of the trilinear field at each sample (6 lookups).
    on_the_fly,
    /// A precomputed volume of node gradients (3 float32 per node, central
    /// differences of the nodes), interpolated trilinearly: one lookup of 3
    /// components per sample. Falls back to on_the_fly, with a warning, when
    /// the gradient volume would exceed RenderSettings::gradient_memory.
    precomputed,
};

/// One surface of the isosurface model: where the scalar crosses `value`,
/// lit with the shading coefficients, composited with `opacity`.
struct IsoSurface {
    double value = 0;
    Rgb color{1, 1, 1};
    double opacity = 1;
};

struct RenderSettings {
    int width = 512;
    int height = 512;
    Model model = Model::emission_absorption;
    IntegratorKind integrator = IntegratorKind::preintegrated;
    double step = 0.5;        // in units of the smallest spacing, or world units
    bool step_world = false;  // step_unit "world"
    SamplePoint sample_point = SamplePoint::near;
    Order order = Order::front_to_back;
    double termination = 1e-3;
    /// I_bg; when absent: black, white under the absorption model.
    std::optional<Rgb> background;
    bool transparent = false;  // background "transparent": I_bg = 0, PNG gets alpha
    int threads = 0;           // 0: all hardware threads
    /// Jitter: each pixel's riemann/alpha samples sit at a hashed offset in
    /// their segments instead of sample_point (wood-grain becomes fine noise).
    bool jitter = false;
    std::uint32_t jitter_seed = 0;
    /// Accuracy goal of the reference integrator (per channel, absolute for
    /// radiance ≤ 1, relative above).
    double reference_tolerance = 1e-5;
    Shading shading;
    GradientSource gradient = GradientSource::on_the_fly;
    /// Most bytes a precomputed gradient volume may take (default 2 GiB).
    std::uint64_t gradient_memory = std::uint64_t{2} << 30;
    /// Also compute RayResult::depth and first_hit (Renderer::render then
    /// fills Image::depth and Image::first_hit).
    bool depth_outputs = false;
    /// Iso-values of the isosurface model (at most 16).
    std::vector<IsoSurface> isosurfaces;
    /// Cutting: rays keep only the part of the volume inside the cropping
    /// box and on the kept side of every clipping plane (at most 6); the
    /// uniform segment division applies to what is left (exact).
    std::optional<WorldBox> crop;
    std::vector<ClipPlane> clip_planes;
    /// Exact empty-space skipping (macrocells where the medium is exactly
    /// zero, and for riemann/alpha with SIMD the blocks of 2×2×2 cells
    /// wholly below the medium's zero range; the image is unchanged bit for
    /// bit). Off only to measure it: every sample is then interpolated and
    /// classified (those found zero still add nothing).
    bool skip_empty = true;
    /// SIMD classification of point samples (riemann, alpha) with runtime
    /// dispatch; bit-identical to the scalar path. Off only to measure it.
    bool simd = true;
    /// Ray packets: riemann and alpha, unshaded, front to back, with SIMD
    /// (skipping or not), trace a tile's rays one per SIMD lane, each lane
    /// walking and sampling its own ray; so do the pre-integrated
    /// integrators where they skip and empty macrocells join
    /// (EmptySpace::joins_empty) (docs/performance.md "Ray packets");
    /// bit-identical to tracing them one by one. Off only to measure it.
    bool packets = true;
    /// A renderer that keeps its volume (Renderer(Volume&&, ...)) moves the
    /// samples into bricks of 32³ cells (the x-fastest copy handed back as
    /// they fill) where the volume has at least this many bytes, the bricks
    /// take at most a quarter more (10 % on the bunny), and its frames take
    /// the unshaded SIMD path of an optical model; the image is unchanged
    /// bit for bit. 64 MiB by default: smaller
    /// volumes stay in cache well enough (docs/performance.md "Bricks").
    std::uint64_t brick_min_bytes = std::uint64_t{64} << 20;
    /// The optical models and isosurfaces may skip by macrocells of 2³
    /// cells where the lattice has at most this many of them (and they
    /// would skip a quarter or more of what 4³ ones evaluate), else by 4³;
    /// the image is unchanged bit for bit. 2²² by default (a 320³ volume):
    /// on larger volumes their tables outgrow the caches and cost memory
    /// (docs/performance.md "Empty-space skipping"). 0 keeps 4³ everywhere.
    std::uint64_t fine_macrocells_max = std::uint64_t{1} << 22;

    /// I_bg as the contract resolves it.
    [[nodiscard]] Rgb background_radiance() const;
    /// Throws Error("render settings", ...) on out-of-range values.
    void validate() const;
};

struct RayResult {
    Rgb radiance{0, 0, 0};
    double alpha = 0.0;
    /// Depth outputs (RenderSettings::depth_outputs; world distance along
    /// the ray, infinite where nothing is hit): the expected termination
    /// depth Σ T·α·t / (1 − T), and the first hit (the first segment with
    /// α > 0; the isosurface model: the first surface, always set).
    double depth = INFINITY;
    double first_hit = INFINITY;
};

/// Called from the rendering threads with (tiles done, tiles in all).
using ProgressFn = std::function<void(int, int)>;

class Renderer {
public:
    /// A scalar volume classified by a transfer function (opacity unit
    /// distance defaults to the volume's smallest spacing). The volume must
    /// outlive the renderer.
    Renderer(const Volume& volume, const TransferFunction& tf, RenderSettings settings);
    /// The same, the renderer keeping the volume: a large one it may
    /// rearrange into bricks in place (RenderSettings::brick_min_bytes),
    /// which speeds up views along the volume's slices without a second copy
    /// in memory. The image is the same bit for bit.
    Renderer(Volume&& volume, const TransferFunction& tf, RenderSettings settings);
    /// Pre-classified grids: density (1 component) and RGB color (3
    /// components) on the same lattice, float32 or float64.
    Renderer(const Volume& density, const Volume& color, RenderSettings settings);
    ~Renderer();
    Renderer(Renderer&&) noexcept;
    Renderer& operator=(Renderer&&) noexcept;

    [[nodiscard]] const RenderSettings& settings() const;
    /// Whether the renderer samples its volume from bricks.
    [[nodiscard]] bool bricked() const;
    /// Whether its frames trace rays in SIMD packets (RenderSettings::packets).
    [[nodiscard]] bool packets() const;
    /// Cells per edge of the macrocells its rays skip by (2 or 4; see
    /// RenderSettings::fine_macrocells_max), or 0 where they skip by none
    /// (skipping off, nothing empty, or the projections' ranges alone).
    [[nodiscard]] int macrocell_cells() const;
    /// The ray integral of one ray (world-space origin and unit direction).
    [[nodiscard]] RayResult trace(const Ray& ray) const;
    /// The whole image; tiles over threads; the result does not depend on
    /// the thread count.
    [[nodiscard]] Image render(const Camera& camera, const ProgressFn& progress = {}) const;
    /// The same image into `into`, whose storage is kept where it already
    /// holds an image of the settings' size (a viewer's or a benchmark's
    /// frame after frame): no allocation and no clearing, as every pixel is
    /// written. After an error `into` holds no complete image.
    void render(const Camera& camera, Image& into, const ProgressFn& progress = {}) const;
    /// The number of segments (samples) the image's rays hold by eq. (8),
    /// before early termination: the work measure of `fathom bench`.
    [[nodiscard]] std::uint64_t count_segments(const Camera& camera) const;

    struct Impl;

private:
    std::unique_ptr<Impl> impl_;
};

/// The sample offset in [0, 1) of pixel (x, y) under jitter
/// (RenderSettings::jitter): a hash of (x, y, seed), deterministic and
/// independent of the thread count (a 32-bit integer hash, "lowbias32").
/// For callers that trace a camera's rays one by one (DiffRenderer's ray API).
double jitter_offset(int x, int y, std::uint32_t seed);

/// Centre and half-diagonal of a volume's box (for orbit cameras).
struct Bounds {
    Vec3 center;
    double radius;
};
Bounds volume_bounds(const Volume& v);

}  // namespace fathom
