// Differentiable rendering (docs/reverse-rendering.md): the forward ray
// integral and, given dL/dI per ray, the gradients of a loss L with respect
// to the medium: pre-classified density σ and RGB color grids, or a scalar
// volume's voxels and its transfer function's control values.
//
// The backward pass re-marches each ray with its forward result known
// (O(1) memory per ray): for segment i with optical depth τ_i and radiance
// C_i, ∂I/∂C_i = T_{i−1} and ∂I/∂τ_i = −(I − I_{≤i}) (the light from behind
// the segment, as it reaches the camera), so nothing is divided by a
// transmittance and nearly opaque rays stay exact. Per-segment derivatives
// come in closed form (riemann, alpha) or through the pre-integrated piece
// integral itself in forward-mode dual numbers (preintegrated,
// preintegrated-simple); they are scattered to the grid nodes by the
// trilinear weights and to the transfer function's control points by the
// piece weights.
#pragma once

#include <cstdint>
#include <memory>
#include <span>
#include <vector>

#include "fathom/camera.h"
#include "fathom/image.h"
#include "fathom/render.h"
#include "fathom/transfer_function.h"
#include "fathom/volume.h"

namespace fathom {

/// dL/dI of one ray: the radiance (RGB) and the opacity α.
struct RayAdjoint {
    Rgb radiance{0, 0, 0};
    double alpha = 0;
};

/// Gradients of a loss, summed over rays. Only the members of the renderer's
/// kind are sized (the others stay empty).
struct Gradients {
    /// Pre-classified grids: ∂L/∂σ per node, ∂L/∂c per node and channel
    /// (node-major, as a 3-component Volume stores it).
    std::vector<double> density, color;
    /// Scalar volume: ∂L/∂v per node. Left empty, the voxels' gradient is
    /// not computed (fitting the transfer function alone).
    std::vector<double> scalar;
    /// Transfer function: per alpha point, ∂L/∂(the value as written: opacity
    /// or extinction); per color point, ∂L/∂(r, g, b) (or q).
    std::vector<double> tf_alpha;
    std::vector<Rgb> tf_color;

    /// Sets every member to zero, keeping sizes.
    void zero();
    /// Adds another set of the same sizes.
    Gradients& operator+=(const Gradients& o);
};

/// The differentiable renderer. Supports the emission–absorption,
/// absorption and emission models with the riemann, alpha, preintegrated
/// and preintegrated-simple integrators, in both orders (the backward pass
/// runs front to back; back-to-front renders the same function), jitter,
/// cropping and clipping. Not differentiable, and refused: shading, gradient
/// opacity, the projection and isosurface models, the reference integrator.
/// Empty-space skipping (unless skip_empty_density is on) and SIMD do not
/// apply (an empty region still has a gradient); the forward result equals
/// Renderer's front to back with skip_empty and simd off, bit for bit; back to front it is the same sum
/// (without early termination) in the other order.
class DiffRenderer {
public:
    /// Pre-classified grids (float32 or float64, same lattice).
    DiffRenderer(const Volume& density, const Volume& color, RenderSettings settings);
    /// A scalar volume classified by a transfer function. The volume must
    /// outlive the renderer.
    DiffRenderer(const Volume& volume, const TransferFunction& tf, RenderSettings settings);
    ~DiffRenderer();
    DiffRenderer(DiffRenderer&&) noexcept;
    DiffRenderer& operator=(DiffRenderer&&) noexcept;

    [[nodiscard]] const RenderSettings& settings() const;

    /// Training speed-up for pre-classified grids (Plenoxels-style pruning):
    /// both passes skip the macrocells (4³ cells; 8³ pre-integrated) where
    /// every density node is exactly 0, as Renderer's empty-space skipping
    /// does. The forward result is unchanged bit for bit (those segments are
    /// exactly (1, 0)); the backward pass computes no gradient inside them,
    /// so an emptied region stays empty (it can regrow from its border: the
    /// nodes a macrocell shares with a non-empty one still get gradients).
    /// The macrocells are built from the density now: call again after
    /// changing it; `false` turns skipping off (the default: exact gradients).
    void skip_empty_density(bool on);
    /// As skip_empty_density(true), but the macrocells skipped are those
    /// where every node of `occupied` (the density's lattice, any type) is
    /// exactly 0; the caller guarantees that the density is 0 there (else
    /// the forward result changes). Built once: the density may then change
    /// elsewhere without a rebuild (fathom::Fitter's pruning).
    void skip_empty_where(const Volume& occupied);
    /// The fraction of macrocells skipped (0 when skipping is off).
    [[nodiscard]] double empty_fraction() const;
    /// Gradients sized for this renderer, zero.
    [[nodiscard]] Gradients make_gradients() const;

    /// One ray (world-space origin, unit direction); sample_offset ∈ [0, 1)
    /// places the point samples as jitter does (< 0: the sample_point setting).
    [[nodiscard]] RayResult forward(const Ray& ray, double sample_offset = -1.0) const;
    /// Adds ∂L/∂(inputs) of one ray into g, given its forward result and dL/dI.
    void backward(const Ray& ray, const RayResult& forward, const RayAdjoint& adjoint, Gradients& g,
                  double sample_offset = -1.0) const;

    /// Many rays over the settings' threads, with optional per-ray sample
    /// offsets (empty: the sample_point setting for all). Forward results
    /// come in ray order.
    [[nodiscard]] std::vector<RayResult> forward(std::span<const Ray> rays,
                                                 std::span<const double> offsets = {}) const;
    /// Adds the gradients of many rays into g. Each thread sums a fixed,
    /// contiguous block of rays: the first into g itself, the others into
    /// their own buffers, added to g in thread order at the end. The result
    /// is deterministic for a given thread count (and, with one thread,
    /// equals the one-ray calls in order).
    void backward(std::span<const Ray> rays, std::span<const RayResult> forward,
                  std::span<const RayAdjoint> adjoints, Gradients& g,
                  std::span<const double> offsets = {}) const;

    /// The image of a camera (jitter as Renderer::render), and its backward
    /// pass given dL/d(pixel) as H×W×4 floats (RGBA) in `adjoint` (each
    /// ray's forward result is recomputed in double; pixels with a zero
    /// adjoint are skipped).
    [[nodiscard]] Image render(const Camera& camera) const;
    void backward(const Camera& camera, std::span<const float> adjoint, Gradients& g) const;

    struct Impl;

private:
    std::unique_ptr<Impl> impl_;
};

}  // namespace fathom
