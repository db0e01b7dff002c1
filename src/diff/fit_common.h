// What the fitters share (src/diff/fit.cpp, src/diff/fit_tf.cpp): random ray
// batches from a view set, the MSE loss and its adjoints, Adam, and the PSNR
// of a view set.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstddef>
#include <random>
#include <vector>

#include "fathom/differentiable.h"
#include "fathom/render.h"
#include "fathom/views.h"

#include "core/parallel.h"

namespace fathom::fit {

/// Render settings of a fit: its integrator, step, background and threads.
template <class Options>
RenderSettings render_settings(const Options& o, int w, int h) {
    RenderSettings s;
    s.width = w;
    s.height = h;
    s.integrator = o.integrator;
    s.step = o.step;
    s.background = o.background;
    s.threads = o.threads;
    return s;
}

/// A batch of random rays (view and pixel uniform, jittered sample offsets)
/// with their targets: the pixel's color composited over the background.
struct Batch {
    std::vector<Ray> rays;
    std::vector<double> offsets;
    std::vector<Rgb> target;
};

inline Batch sample_batch(const ViewSet& vs, std::size_t n, const Rgb& bg, std::mt19937_64& rng) {
    const int W = vs.width(), H = vs.height();
    Batch b{std::vector<Ray>(n), std::vector<double>(n), std::vector<Rgb>(n)};
    std::uniform_int_distribution<std::size_t> pick_view(0, vs.views.size() - 1);
    std::uniform_int_distribution<int> px(0, W - 1), py(0, H - 1);
    std::uniform_real_distribution<double> u01(0.0, 1.0);
    for (std::size_t r = 0; r < n; ++r) {
        const View& v = vs.views[pick_view(rng)];
        const int x = px(rng), y = py(rng);
        b.rays[r] = v.camera.generate(x, y, W, H);
        b.offsets[r] = u01(rng);
        const float* p = v.image.pixel(x, y);
        for (int c = 0; c < 3; ++c) b.target[r][c] = p[c] * p[3] + bg[c] * (1.0 - p[3]);
    }
    return b;
}

/// The mean squared error over rays and channels, and dL/dI per ray.
inline double mse_adjoints(const std::vector<RayResult>& fwd, const std::vector<Rgb>& target,
                           std::vector<RayAdjoint>& adj) {
    adj.assign(fwd.size(), RayAdjoint{});
    const double norm = 1.0 / (3.0 * static_cast<double>(fwd.size()));
    double mse = 0;
    for (std::size_t r = 0; r < fwd.size(); ++r)
        for (int c = 0; c < 3; ++c) {
            const double e = fwd[r].radiance[c] - target[r][c];
            mse += e * e * norm;
            adj[r].radiance[c] = 2 * e * norm;
        }
    return mse;
}

inline double psnr_of(double mse) {
    return -10.0 * std::log10(std::max(mse, 1e-30));
}

/// Adam (β = 0.9, 0.999; ε = 1e−8) at step t ≥ 1: the bias corrections.
struct AdamStep {
    double lr, b1, b2;
    AdamStep(double rate, long t)
        : lr(rate),
          b1(1 - std::pow(0.9, static_cast<double>(t))),
          b2(1 - std::pow(0.999, static_cast<double>(t))) {}
    /// Updates one parameter p = scale·x with gradient g (w.r.t. p),
    /// projected onto [lo, hi]; x, m, v stored as T.
    template <class T>
    void operator()(T& x, T& m, T& v, double g, double scale, double lo, double hi) const {
        m = static_cast<T>(0.9 * m + (1 - 0.9) * g);
        v = static_cast<T>(0.999 * v + (1 - 0.999) * g * g);
        const double step = lr * (m / b1) / (std::sqrt(v / b2) + 1e-8);
        const double p = std::clamp(scale * x - step, lo, hi);
        x = static_cast<T>(p / scale);
    }
};

/// One Adam step on n parameters (all of them: a dense update).
template <class T>
void adam_update(T* x, T* m, T* v, const double* g, std::size_t n, double lr, long t, double scale, double lo,
                 double hi) {
    const AdamStep step(lr, t);
    for (std::size_t i = 0; i < n; ++i) step(x[i], m[i], v[i], g[i], scale, lo, hi);
}

/// Mean PSNR over a view set's images (RGB over the background) of what
/// `render(camera)` gives.
template <class Render>
double view_set_psnr(const ViewSet& views, const Rgb& bg, Render&& render) {
    double sum = 0;
    for (const View& v : views.views) {
        const Image img = render(v.camera);
        double se = 0;
        for (std::size_t p = 0; p < img.rgba.size(); p += 4) {
            const double a = v.image.rgba[p + 3];
            for (std::size_t c = 0; c < 3; ++c) {
                const double t = v.image.rgba[p + c] * a + bg[c] * (1.0 - a);
                const double e = img.rgba[p + c] - t;
                se += e * e;
            }
        }
        sum += psnr_of(se / (3.0 * static_cast<double>(img.rgba.size() / 4)));
    }
    return sum / static_cast<double>(views.views.size());
}

}  // namespace fathom::fit
