// Reconstruction by reverse rendering (docs/reverse-rendering.md): density
// and color grids fitted to a view set with Adam, an MSE loss and
// total-variation regularisation, coarse to fine, on random ray batches.
#pragma once

#include <array>
#include <cstdint>
#include <filesystem>
#include <memory>
#include <vector>

#include "fathom/math.h"
#include "fathom/render.h"
#include "fathom/transfer_function.h"
#include "fathom/views.h"
#include "fathom/volume.h"

namespace fathom {

struct FitOptions {
    /// The world box the grids cover.
    std::array<Vec3, 2> bounds{};
    /// Nodes along the box's longest side at the end, and at the start; the
    /// grid doubles from start_grid until it reaches grid (32 → 64 → 128).
    int grid = 128;
    int start_grid = 32;
    int iterations = 2000;
    /// Iterations on each grid before the last (the last entry repeats for
    /// any further ones; the last grid runs the rest); empty: each grid an
    /// equal share of `iterations`. A coarse grid stops improving long
    /// before a fine one does.
    std::vector<int> level_iterations;
    /// Rays per iteration (random views and pixels).
    int batch = 4096;
    /// Adam step sizes on the first grid, halved with each doubling: density
    /// in optical depth per voxel of the current grid (σ·spacing), color in
    /// color units. Updates are sparse: only the nodes a batch's rays reach
    /// get a total-variation gradient and an Adam step.
    double lr_density = 0.01, lr_color = 0.01;
    /// The step sizes decay exponentially over each grid level to this
    /// fraction of their value at its last iteration (1: constant).
    double lr_final = 1.0;
    /// Total variation (mean over nodes of the squared differences to the
    /// next node along x, y and z), of the same scaled density and of color.
    double tv_density = 3e-3, tv_color = 3e-3;
    /// What the images' transparent parts show (alpha-composited targets).
    Rgb background{1, 1, 1};
    IntegratorKind integrator = IntegratorKind::alpha;
    /// Sample step in voxels of the current grid.
    double step = 0.5;
    std::uint32_t seed = 1;
    int threads = 0;
    /// Pruning (as Plenoxels' occupancy grid): every 50 iterations, each
    /// block of 4³ cells whose density nodes all lie below `prune` (optical
    /// depth per voxel) is set to exactly 0 (its Adam moments too) and
    /// frozen there for the rest of the grid level; with `skip_empty`, both
    /// passes skip the pruned blocks (DiffRenderer::skip_empty_where: exact,
    /// since they are 0). Off: prune = 0.
    double prune = 1e-2;
    bool skip_empty = true;

    /// Throws Error("fit options", ...) on out-of-range values.
    void validate() const;
};

struct FitStats {
    int iteration = 0;  // iterations done
    int grid = 0;       // nodes along the longest side now
    double loss = 0;    // the batch's MSE (per channel) plus the TV terms
    double psnr = 0;    // of the batch's MSE alone
    double rays_per_second = 0;
    double empty = 0;  // fraction of the density's macrocells skipped as empty (0 without skip_empty)
};

class Fitter {
public:
    /// The view set must outlive the fitter.
    Fitter(const ViewSet& train, FitOptions options);
    ~Fitter();
    Fitter(Fitter&&) noexcept;
    Fitter& operator=(Fitter&&) noexcept;

    /// One iteration: a ray batch, its gradients, an Adam step, the grid
    /// doubled when its time comes.
    FitStats step();
    [[nodiscard]] int iteration() const;
    [[nodiscard]] bool done() const;
    [[nodiscard]] const FitOptions& options() const;
    /// The current grids: σ (1/world unit, float32) and RGB color (float32, 3 components).
    [[nodiscard]] const Volume& density() const;
    [[nodiscard]] const Volume& color() const;
    /// Render settings that reproduce the fit's images from the grids.
    [[nodiscard]] RenderSettings render_settings(int width, int height) const;
    /// Mean PSNR (dB) over a view set's images (RGB composited over the
    /// background), rendered from the current grids.
    [[nodiscard]] double psnr(const ViewSet& views) const;

    /// Writes the state (grids, Adam moments, iteration, random state) to a
    /// folder; resume() continues from it exactly (same results as without
    /// the interruption, for a given thread count).
    void save_checkpoint(const std::filesystem::path& dir) const;
    static Fitter resume(const ViewSet& train, FitOptions options, const std::filesystem::path& dir);

    struct Impl;

private:
    explicit Fitter(std::unique_ptr<Impl> impl);
    std::unique_ptr<Impl> impl_;
};

/// Transfer-function fitting: the control values of a TF (positions fixed)
/// fitted to a view set of a scalar volume.
struct TfFitOptions {
    int iterations = 300;
    int batch = 4096;
    /// Adam step sizes: alpha values (opacity, or extinction in 1/world unit
    /// when the TF is written so) and color values.
    double lr_alpha = 0.01, lr_color = 0.02;
    Rgb background{1, 1, 1};
    IntegratorKind integrator = IntegratorKind::preintegrated;
    /// Sample step in units of the volume's smallest spacing.
    double step = 1.0;
    std::uint32_t seed = 1;
    int threads = 0;
    void validate() const;
};

class TfFitter {
public:
    /// `start` gives the control positions, the alpha kind and the start
    /// values. The volume and the view set must outlive the fitter.
    TfFitter(const Volume& volume, TransferFunction start, const ViewSet& views, TfFitOptions options);
    ~TfFitter();
    TfFitter(TfFitter&&) noexcept;
    TfFitter& operator=(TfFitter&&) noexcept;

    FitStats step();
    [[nodiscard]] int iteration() const;
    [[nodiscard]] bool done() const;
    [[nodiscard]] const TransferFunction& transfer_function() const;
    [[nodiscard]] RenderSettings render_settings(int width, int height) const;
    [[nodiscard]] double psnr(const ViewSet& views) const;

    struct Impl;

private:
    std::unique_ptr<Impl> impl_;
};

/// `tf` with every alpha value set to `alpha` and every color to gray 0.5:
/// the flat start of a TF fit, keeping the positions.
TransferFunction flattened(TransferFunction tf, double alpha);

}  // namespace fathom
