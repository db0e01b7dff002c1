// Transfer-function fitting (include/fathom/fit.h, docs/reverse-rendering.md).
#include <chrono>
#include <random>

#include "fathom/differentiable.h"
#include "fathom/error.h"
#include "fathom/fit.h"

#include "diff/fit_common.h"

namespace fathom {

void TfFitOptions::validate() const {
    auto fail = [](const std::string& m) { throw Error("fit-tf options", m); };
    if (iterations < 1 || iterations > 10000000) fail("iterations must be in 1..10^7");
    if (batch < 1 || batch > 1 << 24) fail("batch must be in 1..2^24");
    if (!(lr_alpha > 0) || !(lr_color > 0) || !std::isfinite(lr_alpha) || !std::isfinite(lr_color))
        fail("learning rates must be positive");
    if (!(step > 0) || !std::isfinite(step)) fail("step must be positive");
    if (integrator == IntegratorKind::reference) fail("the reference integrator is not differentiable");
    if (threads < 0) fail("threads must be ≥ 0");
}

TransferFunction flattened(TransferFunction tf, double alpha) {
    for (auto& p : tf.alpha_points) p.second = alpha;
    for (auto& p : tf.color_points) p.second = {0.5, 0.5, 0.5};
    tf.name = tf.name.empty() ? "fitted" : tf.name + " (fitted)";
    return tf;
}

struct TfFitter::Impl {
    const Volume* volume = nullptr;
    const ViewSet* views = nullptr;
    TfFitOptions o;
    TransferFunction tf;
    std::vector<double> alpha, m_a, v_a, color, m_c, v_c;  // parameters and Adam moments
    int iteration = 0;
    std::mt19937_64 rng;

    [[nodiscard]] RenderSettings settings(int w, int h) const { return fit::render_settings(o, w, h); }
    void sync_tf() {
        for (std::size_t i = 0; i < alpha.size(); ++i) tf.alpha_points[i].second = alpha[i];
        for (std::size_t i = 0; i < tf.color_points.size(); ++i)
            for (int c = 0; c < 3; ++c) tf.color_points[i].second[c] = color[3 * i + c];
    }
};

TfFitter::TfFitter(const Volume& volume, TransferFunction start, const ViewSet& views, TfFitOptions options)
    : impl_(std::make_unique<Impl>()) {
    options.validate();
    if (views.views.empty()) throw Error("fit-tf", "the view set has no views");
    Impl& im = *impl_;
    im.volume = &volume;
    im.views = &views;
    im.o = options;
    im.tf = std::move(start);
    im.rng.seed(options.seed);
    for (const auto& p : im.tf.alpha_points) im.alpha.push_back(p.second);
    for (const auto& p : im.tf.color_points)
        im.color.insert(im.color.end(), p.second.begin(), p.second.end());
    im.m_a.assign(im.alpha.size(), 0.0);
    im.v_a.assign(im.alpha.size(), 0.0);
    im.m_c.assign(im.color.size(), 0.0);
    im.v_c.assign(im.color.size(), 0.0);
    (void)DiffRenderer(volume, im.tf, im.settings(1, 1));  // the volume and TF are differentiable
}

TfFitter::~TfFitter() = default;
TfFitter::TfFitter(TfFitter&&) noexcept = default;
TfFitter& TfFitter::operator=(TfFitter&&) noexcept = default;

FitStats TfFitter::step() {
    Impl& im = *impl_;
    const auto t0 = std::chrono::steady_clock::now();
    const DiffRenderer r(*im.volume, im.tf, im.settings(1, 1));
    const auto B = static_cast<std::size_t>(im.o.batch);
    const fit::Batch batch = fit::sample_batch(*im.views, B, im.o.background, im.rng);
    const auto fwd = r.forward(batch.rays, batch.offsets);
    std::vector<RayAdjoint> adj;
    const double mse = fit::mse_adjoints(fwd, batch.target, adj);
    Gradients g = r.make_gradients();
    g.scalar.clear();  // the voxels stay as they are
    r.backward(batch.rays, fwd, adj, g, batch.offsets);
    std::vector<double> gc;
    for (const Rgb& c : g.tf_color) gc.insert(gc.end(), c.begin(), c.end());
    ++im.iteration;
    const bool opacity = im.tf.alpha_kind == TransferFunction::Alpha::opacity;
    fit::adam_update(im.alpha.data(), im.m_a.data(), im.v_a.data(), g.tf_alpha.data(), im.alpha.size(),
                     im.o.lr_alpha, im.iteration, 1.0, 0.0, opacity ? 1.0 - 1e-6 : INFINITY);
    // Colors of a "color" TF are reflectances in [0, 1]; emission q is ≥ 0.
    fit::adam_update(im.color.data(), im.m_c.data(), im.v_c.data(), gc.data(), im.color.size(), im.o.lr_color,
                     im.iteration, 1.0, 0.0, im.tf.associated ? INFINITY : 1.0);
    im.sync_tf();
    const double secs = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    return {im.iteration, 0, mse, fit::psnr_of(mse), static_cast<double>(B) / std::max(secs, 1e-9)};
}

int TfFitter::iteration() const {
    return impl_->iteration;
}
bool TfFitter::done() const {
    return impl_->iteration >= impl_->o.iterations;
}
const TransferFunction& TfFitter::transfer_function() const {
    return impl_->tf;
}
RenderSettings TfFitter::render_settings(int width, int height) const {
    return impl_->settings(width, height);
}
double TfFitter::psnr(const ViewSet& views) const {
    if (views.views.empty()) throw Error("fit-tf", "the view set has no views");
    const Renderer r(*impl_->volume, impl_->tf, impl_->settings(views.width(), views.height()));
    return fit::view_set_psnr(views, impl_->o.background, [&](const Camera& c) { return r.render(c); });
}

}  // namespace fathom
