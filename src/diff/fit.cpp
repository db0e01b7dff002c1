// Reconstruction by reverse rendering (include/fathom/fit.h).
#include "fathom/fit.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <random>
#include <sstream>
#include <string>
#include <type_traits>

#include <nlohmann/json.hpp>

#include "fathom/differentiable.h"
#include "fathom/error.h"
#include "fathom/io.h"

#include "diff/fit_common.h"
#include "volume/sampler.h"

namespace fathom {

namespace fs = std::filesystem;

namespace {

/// Iterations on grid level l before the last under `level_iterations`
/// (FitOptions): its entry l, or the last entry for any further level.
long coarse_iterations(const std::vector<int>& level_iterations, long l) {
    return l < static_cast<long>(level_iterations.size()) ? level_iterations[static_cast<std::size_t>(l)]
                                                          : level_iterations.back();
}

}  // namespace

void FitOptions::validate() const {
    auto fail = [](const std::string& m) { throw Error("fit options", m); };
    for (int a = 0; a < 3; ++a)
        if (!(bounds[1][a] > bounds[0][a]) || !std::isfinite(bounds[0][a]) || !std::isfinite(bounds[1][a]))
            fail("the bounds must have min < max on every axis");
    if (grid < 4 || grid > 1024) fail("grid must be in 4..1024");
    if (start_grid < 4 || start_grid > grid) fail("start_grid must be in 4..grid");
    if (iterations < 1 || iterations > 10000000) fail("iterations must be in 1..10^7");
    if (batch < 1 || batch > 1 << 24) fail("batch must be in 1..2^24");
    if (!(lr_density > 0) || !(lr_color > 0) || !std::isfinite(lr_density) || !std::isfinite(lr_color))
        fail("learning rates must be positive");
    if (!(tv_density >= 0) || !(tv_color >= 0) || !std::isfinite(tv_density) || !std::isfinite(tv_color))
        fail("TV weights must be ≥ 0");
    if (!(step > 0) || !std::isfinite(step)) fail("step must be positive");
    if (integrator == IntegratorKind::reference) fail("the reference integrator is not differentiable");
    if (threads < 0) fail("threads must be ≥ 0");
    if (!(prune >= 0) || !std::isfinite(prune)) fail("prune must be ≥ 0");
    if (!(lr_final > 0) || lr_final > 1) fail("lr_final must be in (0, 1]");
    int coarse_levels = 0;  // grids before the last
    for (int n = start_grid; n < grid; n *= 2) ++coarse_levels;
    if (static_cast<int>(level_iterations.size()) > coarse_levels)
        fail("level iterations name " + std::to_string(level_iterations.size()) + " grids, but only " +
             std::to_string(coarse_levels) + " come before the last");
    for (const int n : level_iterations)
        if (n < 1) fail("level iterations must be ≥ 1");
    long coarse = 0;
    if (!level_iterations.empty())
        for (long l = 0; l < coarse_levels; ++l) coarse += coarse_iterations(level_iterations, l);
    if (coarse >= iterations) fail("the grids before the last must leave iterations for the last");
}

namespace {

/// Grid sizes from start_grid doubling up to grid (the last is grid).
std::vector<int> level_sizes(const FitOptions& o) {
    std::vector<int> s{o.start_grid};
    while (s.back() < o.grid) s.push_back(std::min(o.grid, 2 * s.back()));
    return s;
}

/// The lattice over the bounds with n nodes along the longest side (cubic
/// voxels; the other sides rounded up to whole voxels).
Volume make_grid(const FitOptions& o, int n, int comps) {
    const Vec3 e = o.bounds[1] - o.bounds[0];
    const double s = std::max({e.x, e.y, e.z}) / (n - 1);
    std::array<std::int64_t, 3> dims{};
    for (int a = 0; a < 3; ++a)
        dims[a] = std::max<std::int64_t>(2, static_cast<std::int64_t>(std::ceil(e[a] / s - 1e-9)) + 1);
    Volume v(dims, DType::f32, comps);
    v.set_spacing({s, s, s});
    v.set_origin(o.bounds[0]);
    return v;
}

/// `to` resampled from `from` (trilinear, at to's node positions).
void resample(const Volume& from, Volume& to) {
    const GridSampler<float> g(from);
    const Mat3 w2i = from.axes().inverse();
    float* out = to.data<float>();
    const int C = to.components();
    std::int64_t n = 0;
    for (std::int64_t k = 0; k < to.dims()[2]; ++k)
        for (std::int64_t j = 0; j < to.dims()[1]; ++j)
            for (std::int64_t i = 0; i < to.dims()[0]; ++i, ++n) {
                const Vec3 p = w2i * (to.index_to_world({static_cast<double>(i), static_cast<double>(j),
                                                         static_cast<double>(k)}) -
                                      from.origin());
                const GridCell cell = g.cell(p);
                for (int c = 0; c < C; ++c) out[n * C + c] = static_cast<float>(g.interpolate(cell, c));
            }
}

/// The gradient of the squared-difference total variation
/// (w/N)·Σ_pairs (p_m − p_n)² of the parameters p = scale·x, with respect to
/// p at node n, component c (the pairs n takes part in along x, y and z),
/// added into grad; returns n's share of the TV (its pairs towards +x, +y,
/// +z).
double tv_at(const Volume& v, std::int64_t n, int c, double scale, double w, double& grad) {
    const auto& d = v.dims();
    const int C = v.components();
    const float* x = v.data<float>();
    const double k = w / static_cast<double>(v.num_nodes());
    const std::int64_t i = n % d[0], j = (n / d[0]) % d[1], kz = n / (d[0] * d[1]);
    const std::array<std::int64_t, 3> pos{i, j, kz}, stride{1, d[0], d[0] * d[1]};
    const double xn = x[n * C + c];
    double share = 0;
    for (int a = 0; a < 3; ++a) {
        if (pos[a] + 1 < d[a]) {
            const double diff = scale * (x[(n + stride[a]) * C + c] - xn);
            share += k * diff * diff;
            grad -= 2 * k * diff;
        }
        if (pos[a] > 0) grad += 2 * k * scale * (xn - x[(n - stride[a]) * C + c]);
    }
    return share;
}

}  // namespace

struct Fitter::Impl {
    const ViewSet* train = nullptr;
    FitOptions o;
    std::vector<int> levels;
    int level = 0;
    int iteration = 0;
    long adam_t = 0;  // Adam steps on the current grid
    std::mt19937_64 rng;
    Volume density, color;      // σ (1/world unit), c
    Volume m_d, v_d, m_c, v_c;  // Adam moments (density in the scaled unit)
    std::unique_ptr<DiffRenderer> renderer;
    Gradients g;  // kept from one iteration to the next, zero between batches
    std::vector<std::vector<std::size_t>> touched;  // the nodes a batch reached, per thread

    [[nodiscard]] RenderSettings settings(int w, int h) const { return fit::render_settings(o, w, h); }
    [[nodiscard]] double spacing() const { return density.spacing().x; }

    void make_level(int n, bool init) {
        Volume d = make_grid(o, n, 1), c = make_grid(o, n, 3);
        if (init) {
            // Start as a faint gray fog: optical depth 0.05 per voxel.
            const float sigma = static_cast<float>(0.05 / d.spacing().x);
            std::fill(d.data<float>(), d.data<float>() + d.num_nodes(), sigma);
            std::fill(c.data<float>(), c.data<float>() + 3 * c.num_nodes(), 0.5f);
        } else {
            resample(density, d);
            resample(color, c);
        }
        density = std::move(d);
        color = std::move(c);
        m_d = make_grid(o, n, 1);
        v_d = make_grid(o, n, 1);
        m_c = make_grid(o, n, 3);
        v_c = make_grid(o, n, 3);
        adam_t = 0;
        renderer = std::make_unique<DiffRenderer>(density, color, settings(1, 1));
        g = renderer->make_gradients();
        const auto nb = block_dims();
        pruned.assign(static_cast<std::size_t>(nb[0] * nb[1] * nb[2]), 0);
        occupied = Volume(density.dims(), DType::u8);
        apply_pruned();
    }

    /// Pruning (FitOptions::prune): blocks of kBlock³ cells (the alpha
    /// integrator's macrocells) are pruned when all their density nodes lie
    /// below o.prune; a pruned block's nodes are 0 and frozen (no steps)
    /// for the rest of the level, so the renderer skips it without a rebuild
    /// after each step and stays exact.
    static constexpr int kPruneEvery = 50, kBlock = 4;
    std::vector<std::uint8_t> pruned;  // per block
    Volume occupied;                   // u8 per node: 0 where a pruned block has it (frozen at 0)
    double skipped = 0;                // the renderer's fraction of macrocells skipped

    [[nodiscard]] std::array<std::int64_t, 3> block_dims() const {
        std::array<std::int64_t, 3> nb{};
        for (int a = 0; a < 3; ++a) nb[a] = (density.dims()[a] - 2) / kBlock + 1;  // cells 0..d−2
        return nb;
    }
    /// Calls f(node) for the nodes of block b (its boundary included); a
    /// predicate f stops it at the first false (and the result says so).
    template <class F>
    bool for_block_nodes(std::size_t b, F&& f) const {
        const auto& d = density.dims();
        const auto nb = block_dims();
        const std::array<std::int64_t, 3> bi{static_cast<std::int64_t>(b) % nb[0],
                                             static_cast<std::int64_t>(b) / nb[0] % nb[1],
                                             static_cast<std::int64_t>(b) / (nb[0] * nb[1])};
        std::array<std::int64_t, 3> lo{}, hi{};
        for (int a = 0; a < 3; ++a) {
            lo[a] = bi[a] * kBlock;
            hi[a] = std::min<std::int64_t>(lo[a] + kBlock, d[a] - 1);
        }
        for (std::int64_t k = lo[2]; k <= hi[2]; ++k)
            for (std::int64_t j = lo[1]; j <= hi[1]; ++j)
                for (std::int64_t i = lo[0]; i <= hi[0]; ++i)
                    if constexpr (std::is_void_v<std::invoke_result_t<F&, std::size_t>>)
                        f(static_cast<std::size_t>(i + d[0] * (j + d[1] * k)));
                    else if (!f(static_cast<std::size_t>(i + d[0] * (j + d[1] * k))))
                        return false;
        return true;
    }
    /// The occupancy grid of the pruned blocks, and the renderer skipping them.
    void apply_pruned() {
        std::uint8_t* occ = occupied.data<std::uint8_t>();
        std::fill(occ, occ + occupied.num_nodes(), std::uint8_t{1});
        for (std::size_t b = 0; b < pruned.size(); ++b)
            if (pruned[b]) for_block_nodes(b, [&](std::size_t n) { occ[n] = 0; });
        if (o.skip_empty) renderer->skip_empty_where(occupied);
        skipped = o.skip_empty ? renderer->empty_fraction() : 0.0;
    }
    /// Prunes the blocks whose density nodes all lie below o.prune (optical
    /// depth per voxel), decided before any is cleared; their moments too.
    void prune_blocks() {
        const double limit = o.prune / spacing();
        float* x = density.data<float>();
        float* md = m_d.data<float>();
        float* vd = v_d.data<float>();
        std::vector<std::size_t> low;
        for (std::size_t b = 0; b < pruned.size(); ++b)
            if (!pruned[b] && for_block_nodes(b, [&](std::size_t n) { return x[n] < limit; }))
                low.push_back(b);
        for (const std::size_t b : low) {
            pruned[b] = 1;
            for_block_nodes(b, [&](std::size_t n) { x[n] = md[n] = vd[n] = 0.0f; });
        }
        apply_pruned();
    }

    /// The first iteration of level l (l = levels: o.iterations):
    /// o.level_iterations on each level before the last, or equal shares.
    [[nodiscard]] long level_begin(long l) const {
        const auto L = static_cast<long>(levels.size());
        if (l >= L) return o.iterations;
        if (o.level_iterations.empty()) return (l * o.iterations + L - 1) / L;  // ⌈l·N/L⌉
        long begin = 0;
        for (long k = 0; k < l; ++k) begin += coarse_iterations(o.level_iterations, k);
        return begin;
    }
    /// The level the schedule puts iteration i on.
    [[nodiscard]] int level_at(int i) const {
        const auto L = static_cast<long>(levels.size());
        long l = 0;
        while (l + 1 < L && i >= level_begin(l + 1)) ++l;
        return static_cast<int>(l);
    }

    FitStats step() {
        const auto t0 = std::chrono::steady_clock::now();
        if (level_at(iteration) > level) {  // (a resumed fit with more iterations never goes back)
            level = level_at(iteration);
            make_level(levels[static_cast<std::size_t>(level)], false);
        }
        const auto B = static_cast<std::size_t>(o.batch);
        const fit::Batch batch = fit::sample_batch(*train, B, o.background, rng);
        const auto fwd = renderer->forward(batch.rays, batch.offsets);
        std::vector<RayAdjoint> adj;
        const double mse = fit::mse_adjoints(fwd, batch.target, adj);
        renderer->backward(batch.rays, fwd, adj, g, batch.offsets);
        // Density is optimised as optical depth per voxel p = σ·s: ∂L/∂p = ∂L/∂σ / s.
        const double s = spacing();
        // The step sizes hold for the first grid and halve with each doubling:
        // a voxel's optical depth halves, and fewer rays reach each node.
        double lr_scale = static_cast<double>(o.start_grid) / levels[static_cast<std::size_t>(level)];
        if (o.lr_final != 1.0) {  // exponential decay over the level, to lr_final at its end
            const double b = static_cast<double>(level_begin(level)),
                         e = static_cast<double>(level_begin(level + 1));
            lr_scale *=
                std::pow(o.lr_final, std::clamp((iteration - b) / std::max(1.0, e - 1 - b), 0.0, 1.0));
        }
        ++adam_t;
        const fit::AdamStep step_d(o.lr_density * lr_scale, adam_t), step_c(o.lr_color * lr_scale, adam_t);
        float* xd = density.data<float>();
        float* md = m_d.data<float>();
        float* vd = v_d.data<float>();
        float* xc = color.data<float>();
        float* mc = m_c.data<float>();
        float* vc = v_c.data<float>();
        // Sparse ("lazy") updates: only the nodes this batch's rays reached
        // (nonzero gradient) get a TV gradient and an Adam step, as sparse
        // Adam does; others keep their values and moments. (A dense TV
        // gradient would be normalised by Adam into full-size steps at nodes
        // no ray constrains.) Node ranges over the threads: gradients first
        // (TV reads the values before any update), then steps.
        const int nt = resolve_threads(o.threads);
        const std::uint8_t* occ = occupied.data<std::uint8_t>();
        touched.resize(static_cast<std::size_t>(nt));
        std::vector<double> tv(static_cast<std::size_t>(nt), 0.0);
        parallel_blocks(g.density.size(), nt, [&](std::size_t b, std::size_t e, int t) {
            auto& mine = touched[static_cast<std::size_t>(t)];
            mine.clear();
            double share = 0;
            for (std::size_t n = b; n < e; ++n) {
                if (g.density[n] == 0.0 && g.color[3 * n] == 0.0 && g.color[3 * n + 1] == 0.0 &&
                    g.color[3 * n + 2] == 0.0)
                    continue;
                if (occ[n] == 0) {  // pruned: frozen at 0 (a border node of a skipped macrocell)
                    g.density[n] = g.color[3 * n] = g.color[3 * n + 1] = g.color[3 * n + 2] = 0.0;
                    continue;
                }
                mine.push_back(n);
                double gd = g.density[n] / s;
                share += tv_at(density, static_cast<std::int64_t>(n), 0, s, o.tv_density, gd);
                g.density[n] = gd;
                for (int c = 0; c < 3; ++c) {
                    double gc = g.color[3 * n + c];
                    share += tv_at(color, static_cast<std::int64_t>(n), c, 1.0, o.tv_color, gc);
                    g.color[3 * n + c] = gc;
                }
            }
            tv[static_cast<std::size_t>(t)] = share;
        });
        double loss = mse;
        for (const double v : tv) loss += v;
        parallel_blocks(touched.size(), nt, [&](std::size_t b, std::size_t e, int) {
            for (std::size_t t = b; t < e; ++t)
                for (const std::size_t n : touched[t]) {
                    step_d(xd[n], md[n], vd[n], g.density[n], s, 0.0, INFINITY);
                    for (std::size_t c = 0; c < 3; ++c)
                        step_c(xc[3 * n + c], mc[3 * n + c], vc[3 * n + c], g.color[3 * n + c], 1.0, 0.0,
                               1.0);
                    g.density[n] = 0.0;  // zero for the next batch
                    for (std::size_t c = 0; c < 3; ++c) g.color[3 * n + c] = 0.0;
                }
        });
        ++iteration;
        if (o.prune > 0 && iteration % kPruneEvery == 0) prune_blocks();
        const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
        return {iteration,         levels[static_cast<std::size_t>(level)],       loss,
                fit::psnr_of(mse), static_cast<double>(B) / std::max(secs, 1e-9), skipped};
    }
};

Fitter::Fitter(const ViewSet& train, FitOptions options) : impl_(std::make_unique<Impl>()) {
    options.validate();
    if (train.views.empty()) throw Error("fit", "the training set has no views");
    impl_->train = &train;
    impl_->o = options;
    impl_->levels = level_sizes(options);
    impl_->rng.seed(options.seed);
    impl_->make_level(impl_->levels.front(), true);
}

Fitter::Fitter(std::unique_ptr<Impl> impl) : impl_(std::move(impl)) {}
Fitter::~Fitter() = default;
Fitter::Fitter(Fitter&&) noexcept = default;
Fitter& Fitter::operator=(Fitter&&) noexcept = default;

FitStats Fitter::step() {
    return impl_->step();
}
int Fitter::iteration() const {
    return impl_->iteration;
}
bool Fitter::done() const {
    return impl_->iteration >= impl_->o.iterations;
}
const FitOptions& Fitter::options() const {
    return impl_->o;
}
const Volume& Fitter::density() const {
    return impl_->density;
}
const Volume& Fitter::color() const {
    return impl_->color;
}
RenderSettings Fitter::render_settings(int width, int height) const {
    return impl_->settings(width, height);
}

double Fitter::psnr(const ViewSet& views) const {
    if (views.views.empty()) throw Error("fit", "the view set has no views");
    const RenderSettings s = impl_->settings(views.width(), views.height());
    const Renderer r(impl_->density, impl_->color, s);
    return fit::view_set_psnr(views, impl_->o.background, [&](const Camera& c) { return r.render(c); });
}

void Fitter::save_checkpoint(const fs::path& dir) const {
    fs::create_directories(dir);
    const Impl& im = *impl_;
    write_nrrd(dir / "density.nrrd", im.density, false);
    write_nrrd(dir / "color.nrrd", im.color, false);
    write_nrrd(dir / "adam_m_density.nrrd", im.m_d, false);
    write_nrrd(dir / "adam_v_density.nrrd", im.v_d, false);
    write_nrrd(dir / "adam_m_color.nrrd", im.m_c, false);
    write_nrrd(dir / "adam_v_color.nrrd", im.v_c, false);
    std::ostringstream rng;
    rng << im.rng;
    std::vector<std::size_t> pruned_list;
    for (std::size_t b = 0; b < im.pruned.size(); ++b)
        if (im.pruned[b]) pruned_list.push_back(b);
    const nlohmann::json j{{"format", "fathom-fit-checkpoint/1"},
                           {"iteration", im.iteration},
                           {"level", im.level},
                           {"adam_t", im.adam_t},
                           {"rng", rng.str()},
                           {"grid", im.o.grid},
                           {"start_grid", im.o.start_grid},
                           {"batch", im.o.batch},
                           {"seed", im.o.seed},
                           {"pruned_blocks", pruned_list}};
    write_text_file(dir / "state.json", j.dump(2) + "\n");  // last: a complete checkpoint has it
}

Fitter Fitter::resume(const ViewSet& train, FitOptions options, const fs::path& dir) {
    Fitter f(train, options);
    Impl& im = *f.impl_;
    const fs::path state = dir / "state.json";
    const std::string subject = state.string();
    nlohmann::json j;
    long adam_t = 0;
    std::vector<std::size_t> pruned_list;
    try {
        std::ifstream in(state);
        if (!in) throw Error(subject, "no checkpoint here (state.json is missing)");
        j = nlohmann::json::parse(in);
        if (j.value("format", "") != "fathom-fit-checkpoint/1")
            throw Error(subject, "not a fathom fit checkpoint");
        if (j.at("grid").get<int>() != options.grid || j.at("start_grid").get<int>() != options.start_grid ||
            j.at("batch").get<int>() != options.batch)
            throw Error(subject, "the checkpoint was made with another --grid, --start-grid or --batch");
        im.iteration = j.at("iteration").get<int>();
        im.level = j.at("level").get<int>();
        adam_t = j.at("adam_t").get<long>();
        std::istringstream rng(j.at("rng").get<std::string>());
        rng >> im.rng;
        if (!rng) throw Error(subject, "the random state does not read");
        if (j.contains("pruned_blocks")) pruned_list = j.at("pruned_blocks").get<std::vector<std::size_t>>();
    } catch (const nlohmann::json::exception& e) {
        throw Error(subject, std::string("broken checkpoint: ") + e.what());
    }
    if (im.level < 0 || im.level >= static_cast<int>(im.levels.size()) || im.iteration < 0)
        throw Error(subject, "iteration or level out of range");
    im.make_level(im.levels[static_cast<std::size_t>(im.level)], true);
    im.adam_t = adam_t;  // (make_level starts a grid's Adam count at 0)
    auto load = [&](const char* name, Volume& into) {
        Volume v = read_volume(dir / name);
        if (v.dims() != into.dims() || v.components() != into.components() || v.dtype() != DType::f32)
            throw Error((dir / name).string(), "does not match the checkpoint's grid");
        v.set_origin(into.origin());
        v.set_axes(into.axes());
        into = std::move(v);
    };
    load("density.nrrd", im.density);
    load("color.nrrd", im.color);
    load("adam_m_density.nrrd", im.m_d);
    load("adam_v_density.nrrd", im.v_d);
    load("adam_m_color.nrrd", im.m_c);
    load("adam_v_color.nrrd", im.v_c);
    im.renderer = std::make_unique<DiffRenderer>(im.density, im.color, im.settings(1, 1));
    for (const std::size_t b : pruned_list) {
        if (b >= im.pruned.size()) throw Error(subject, "a pruned block lies outside the grid");
        im.pruned[b] = 1;
    }
    im.apply_pruned();
    return f;
}

}  // namespace fathom
