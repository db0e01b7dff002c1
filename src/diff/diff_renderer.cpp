// The differentiable renderer (include/fathom/differentiable.h): one
// front-to-back march per ray computes the forward result; the backward
// march recomputes each segment with its derivatives and hands the adjoints
// to the medium, which scatters them to grid nodes and transfer-function
// points.
#include <algorithm>
#include <atomic>
#include <mutex>
#include <optional>

#include "fathom/differentiable.h"
#include "fathom/error.h"

#include "core/parallel.h"
#include "diff/dual.h"
#include "integrate/exp_neg.h"
#include "integrate/preint_piece.h"
#include "integrate/preintegrated.h"
#include "render/renderer_impl.h"
#include "volume/sampler.h"

namespace fathom {

void Gradients::zero() {
    std::fill(density.begin(), density.end(), 0.0);
    std::fill(color.begin(), color.end(), 0.0);
    std::fill(scalar.begin(), scalar.end(), 0.0);
    std::fill(tf_alpha.begin(), tf_alpha.end(), 0.0);
    std::fill(tf_color.begin(), tf_color.end(), Rgb{0, 0, 0});
}

Gradients& Gradients::operator+=(const Gradients& o) {
    auto add = [](std::vector<double>& a, const std::vector<double>& b) {
        if (a.size() != b.size()) throw Error("gradients", "sizes differ");
        for (std::size_t i = 0; i < a.size(); ++i) a[i] += b[i];
    };
    add(density, o.density);
    add(color, o.color);
    add(scalar, o.scalar);
    add(tf_alpha, o.tf_alpha);
    if (tf_color.size() != o.tf_color.size()) throw Error("gradients", "sizes differ");
    for (std::size_t i = 0; i < tf_color.size(); ++i)
        for (int c = 0; c < 3; ++c) tf_color[i][c] += o.tf_color[i][c];
    return *this;
}

namespace {

/// The eight nodes of a located cell and their trilinear weights.
struct Corners {
    std::array<std::int64_t, 8> node;
    std::array<double, 8> w;
};

Corners corners(const GridCell& c, std::int64_t nx, std::int64_t ny) {
    Corners r{};
    const std::int64_t sy = nx, sz = nx * ny;
    const std::array<std::int64_t, 8> off{0, 1, sy, sy + 1, sz, sz + 1, sz + sy, sz + sy + 1};
    for (int k = 0; k < 8; ++k) {
        const double wx = (k & 1) ? c.fx : 1.0 - c.fx;
        const double wy = (k & 2) ? c.fy : 1.0 - c.fy;
        const double wz = (k & 4) ? c.fz : 1.0 - c.fz;
        r.node[k] = c.base + off[k];
        r.w[k] = wx * wy * wz;
    }
    return r;
}

/// dφ/dx for φ(x) = (1 − e^{−x})/x, the alpha quadrature's weight over δ.
double dphi(double x) {
    if (std::abs(x) < 1e-2) {  // series: −1/2 + x/3 − x²/8 + x³/30 − x⁴/144 + x⁵/840
        return -0.5 + x * (1.0 / 3 + x * (-1.0 / 8 + x * (1.0 / 30 + x * (-1.0 / 144 + x / 840))));
    }
    return (std::exp(-x) * (1.0 + x) - 1.0) / (x * x);
}

/// What the backward march hands each segment: dL/dτ_i and dL/dC_i.
struct SegmentAdjoint {
    double tau;
    Rgb radiance;
};

/// A segment's forward values.
struct SegmentValue {
    double t;  // transmittance e^{−τ}
    Rgb C;     // radiance
};

/// The per-segment work of one integrator over one medium: value(i) gives
/// segment i's (t, C) exactly as the renderer computes them; grad(i, adj)
/// scatters the segment's adjoint into the gradients.
///
/// `runs(i)` gives the run of segments from i on that share a state: its
/// last index and whether the run is empty (every segment (1, 0) exactly,
/// skipped: the sums are unchanged bit for bit, and no gradient is computed
/// there).
struct RunState {
    std::int64_t last;
    bool empty;
};

/// Skipping with the macrocells of a density grid (DiffRenderer::skip_empty_density).
struct MacrocellRuns {
    std::int64_t n;
    const RunFinder* finder;  // nullptr: no skipping
    bool ends;                // pre-integrated: segment i spans ends i − 1 and i
    RunState operator()(std::int64_t i) const {
        if (finder == nullptr) return {n, false};
        if (!ends) {
            const auto r = finder->run(i, +1, n, true);
            return {r.last, r.empty};
        }
        const auto r = finder->run(i - 1, +1, n, true);  // ends i − 1 … r.last in one box
        if (r.last >= i) return {r.last, r.empty};
        // Segment i leaves the macrocell: empty when both of its ends' macrocells are.
        return {i, r.empty && finder->run(i, +1, n, true).empty};
    }
};

/// Calls f(i) for each segment 1..n outside the empty runs, in order, until f
/// returns false (early termination). Returns false when f stopped it.
template <class Runs, class F>
bool for_each_evaluated(std::int64_t n, const Runs& runs, F&& f) {
    for (std::int64_t i = 1; i <= n;) {
        const RunState run = runs(i);
        if (run.empty) {
            i = run.last + 1;
            continue;
        }
        for (; i <= run.last; ++i)
            if (!f(i)) return false;
    }
    return true;
}

template <class Seg, class Runs>
RayResult march_forward(std::int64_t n, double termination, const Rgb& bg, Seg& seg, const Runs& runs) {
    RayResult r;
    double T = 1.0;
    const bool reached_end = for_each_evaluated(n, runs, [&](std::int64_t i) {
        const SegmentValue s = seg.value(i);
        for (int c = 0; c < 3; ++c) r.radiance[c] += T * s.C[c];
        T *= s.t;
        return !(T < termination);
    });
    if (reached_end)
        for (int c = 0; c < 3; ++c) r.radiance[c] += T * bg[c];
    r.alpha = 1.0 - T;
    return r;
}

/// ∂I/∂C_i = T_{i−1}; ∂I/∂τ_i = −(I − I_{≤i}); ∂α/∂τ_i = T_final.
template <class Seg, class Runs>
void march_backward(std::int64_t n, double termination, const RayResult& fwd, const RayAdjoint& adj, Seg& seg,
                    const Runs& runs) {
    const double T_final = 1.0 - fwd.alpha;
    double T = 1.0;
    Rgb acc{0, 0, 0};  // I_{≤i}
    for_each_evaluated(n, runs, [&](std::int64_t i) {
        const SegmentValue s = seg.value(i);
        SegmentAdjoint a{adj.alpha * T_final, {}};
        for (int c = 0; c < 3; ++c) {
            a.radiance[c] = adj.radiance[c] * T;
            acc[c] += T * s.C[c];
            a.tau -= adj.radiance[c] * (fwd.radiance[c] - acc[c]);
        }
        seg.grad(i, a);
        T *= s.t;
        return !(T < termination);
    });
}

// ---------------------------------------------------------------- media ---

/// Pre-classified grids.
template <class D, class C>
struct GridMed {
    GridSampler<D> density;
    GridSampler<C> color;
    struct Sample {
        GridCell cell;
        double sigma;
        Rgb color;
    };
    [[nodiscard]] Sample at(const Vec3& p) const {
        Sample s{density.cell(p), 0, {}};
        s.sigma = density.interpolate(s.cell);
        for (int c = 0; c < 3; ++c) s.color[c] = color.interpolate(s.cell, c);
        return s;
    }
    static constexpr bool associated() { return false; }
    /// Adds dL/dσ and dL/dc at a sample to the nodes around it.
    void scatter(const Sample& s, double dsigma, const Rgb& dcolor, Gradients& g) const {
        const Corners k = corners(s.cell, density.nx, density.ny);
        for (int j = 0; j < 8; ++j) {
            const auto n = static_cast<std::size_t>(k.node[j]);
            g.density[n] += k.w[j] * dsigma;
            for (int c = 0; c < 3; ++c) g.color[3 * n + c] += k.w[j] * dcolor[c];
        }
    }
};

/// A scalar volume through a transfer function.
template <class T>
struct ScalarMed {
    GridSampler<T> grid;
    const Classifier* tf = nullptr;
    const std::vector<double>* alpha_chain = nullptr;  // dσ_k/d(written value_k)
    struct Sample {
        GridCell cell;
        double v;
        double sigma;
        Rgb color;
    };
    [[nodiscard]] Sample at(const Vec3& p) const {
        Sample s{grid.cell(p), 0, 0, {}};
        s.v = grid.interpolate(s.cell);
        s.sigma = tf->sigma(s.v);
        s.color = tf->color(s.v);
        return s;
    }
    [[nodiscard]] bool associated() const { return tf->associated(); }

    /// dL/dv at a point to the nodes around it (unless g.scalar is empty:
    /// the caller wants the transfer function's gradient only).
    void scatter_scalar(const GridCell& cell, double dv, Gradients& g) const {
        if (g.scalar.empty()) return;
        const Corners k = corners(cell, grid.nx, grid.ny);
        for (int j = 0; j < 8; ++j) g.scalar[static_cast<std::size_t>(k.node[j])] += k.w[j] * dv;
    }
    /// Adds dL/dσ(v) and dL/dc(v) to v (slope of the piece) and to the
    /// control points defining the piece.
    void scatter(const Sample& s, double dsigma, const Rgb& dcolor, Gradients& g) const {
        double dv = 0.0;
        {
            const auto& f = tf->sigma_function();
            const std::size_t p = f.piece(s.v);
            const auto& kn = f.knots();
            if (p == 0) {
                g.tf_alpha[0] += dsigma * (*alpha_chain)[0];
            } else if (p >= kn.size()) {
                g.tf_alpha[kn.size() - 1] += dsigma * (*alpha_chain)[kn.size() - 1];
            } else {
                const std::size_t k = p - 1;
                const double inv = f.inverse_widths()[k], w = piece_position(s.v, kn[k], inv);
                g.tf_alpha[k] += (1.0 - w) * dsigma * (*alpha_chain)[k];
                g.tf_alpha[k + 1] += w * dsigma * (*alpha_chain)[k + 1];
                dv += dsigma * (f.values()[k + 1][0] - f.values()[k][0]) * inv;
            }
        }
        {
            const auto& f = tf->color_function();
            const std::size_t p = f.piece(s.v);
            const auto& kn = f.knots();
            if (p == 0) {
                for (int c = 0; c < 3; ++c) g.tf_color[0][c] += dcolor[c];
            } else if (p >= kn.size()) {
                for (int c = 0; c < 3; ++c) g.tf_color[kn.size() - 1][c] += dcolor[c];
            } else {
                const std::size_t k = p - 1;
                const double inv = f.inverse_widths()[k], w = piece_position(s.v, kn[k], inv);
                for (int c = 0; c < 3; ++c) {
                    g.tf_color[k][c] += (1.0 - w) * dcolor[c];
                    g.tf_color[k + 1][c] += w * dcolor[c];
                    dv += dcolor[c] * (f.values()[k + 1][c] - f.values()[k][c]) * inv;
                }
            }
        }
        scatter_scalar(s.cell, dv, g);
    }
};

// ------------------------------------------------------ point-sampled ---

/// riemann and alpha: σ and the source held at one point per segment.
template <Model M, bool kAlpha, class Med>
struct PointSegments {
    const Med& med;
    SampleGrid grid;
    double delta;
    Gradients* g = nullptr;

    struct Local {
        typename Med::Sample s;
        double sa, w;  // σ_a after the model; the radiance weight (δ or (1 − e^{−σδ})/σ)
        double t;      // the segment's transmittance (alpha: 1 − α, as the Renderer)
        Rgb src;       // g after the model
    };
    [[nodiscard]] Local local(std::int64_t i) const {
        Local l{med.at(grid.at(i)), 0, 0, 0, {}};
        // As ScalarMedium::classify / GridMedium::at, then apply_model.
        l.src = l.s.color;
        if (!med.associated())
            for (double& c : l.src) c *= l.s.sigma;
        l.sa = l.s.sigma;
        apply_model<M>(l.sa, l.src);
        if constexpr (kAlpha) {
            const double alpha = preint::one_minus_exp_neg(l.sa * delta);
            l.w = l.sa > 0.0 ? alpha / l.sa : delta;
            l.t = 1.0 - alpha;
        } else {
            l.w = delta;
            l.t = l.sa == 0.0 ? 1.0 : preint::exp_neg(l.sa * delta);
        }
        return l;
    }
    // The backward march asks for value(i), then grad(i): the sample is kept.
    mutable Local last{};
    mutable std::int64_t last_i = -1;

    SegmentValue value(std::int64_t i) const {
        last = local(i);
        last_i = i;
        SegmentValue v{last.t, {}};
        for (int c = 0; c < 3; ++c) v.C[c] = last.src[c] * last.w;
        return v;
    }
    void grad(std::int64_t i, const SegmentAdjoint& a) const {
        const Local l = last_i == i ? last : local(i);
        double dsa = a.tau * delta;  // τ = σ_a·δ
        if constexpr (kAlpha) {
            const double dw = delta * delta * dphi(l.sa * delta);  // ∂w/∂σ_a
            for (int c = 0; c < 3; ++c) dsa += a.radiance[c] * l.src[c] * dw;
        }
        double dsigma = M == Model::emission ? 0.0 : dsa;
        Rgb dcolor{0, 0, 0};
        if constexpr (M != Model::absorption) {
            for (int c = 0; c < 3; ++c) {
                const double dsrc = a.radiance[c] * l.w;  // ∂L/∂g_c
                if (med.associated()) {
                    dcolor[c] = dsrc;
                } else {
                    dcolor[c] = dsrc * l.s.sigma;
                    dsigma += dsrc * l.s.color[c];
                }
            }
        }
        med.scatter(l.s, dsigma, dcolor, *g);
    }
};

// -------------------------------------------------- pre-integrated grids ---

template <Model M, class D, class C>
struct PreintGridSegments {
    const GridMed<D, C>& med;
    SampleGrid grid;  // ends: j at t_near + j·δ
    double delta;
    bool full;
    Gradients* g = nullptr;

    SegmentValue value(std::int64_t i) const {
        const auto f = med.at(grid.at(i - 1)), b = med.at(grid.at(i));
        const Segment s = preintegrate_grid<M>(f.sigma, f.color, b.sigma, b.color, delta, full);
        return {s.transmittance, s.radiance};
    }
    void grad(std::int64_t i, const SegmentAdjoint& a) const {
        using S = Dual<8>;
        const auto f = med.at(grid.at(i - 1)), b = med.at(grid.at(i));
        S sf = S::variable(f.sigma, 0), sb = S::variable(b.sigma, 1);
        std::array<S, 3> cf, cb;
        for (int c = 0; c < 3; ++c) {
            cf[c] = S::variable(f.color[c], 2 + c);
            cb[c] = S::variable(b.color[c], 5 + c);
        }
        preint::QuadraticT<S> q = preint::particle_source(sf, sb, cf, cb);
        if constexpr (M == Model::absorption) q = {};
        if constexpr (M == Model::emission) sf = sb = S(0.0);
        const auto r = preint::integrate_piece_t<S>(S(delta), sf, sb, q, full);
        std::array<double, 8> d{};
        for (int k = 0; k < 8; ++k) {
            d[k] = a.tau * r.depth.d[k];
            for (int c = 0; c < 3; ++c) d[k] += a.radiance[c] * r.radiance[c].d[k];
        }
        med.scatter(f, d[0], {d[2], d[3], d[4]}, *g);
        med.scatter(b, d[1], {d[5], d[6], d[7]}, *g);
    }
};

// ------------------------------------------ pre-integrated scalar volume ---

/// One pre-integrated segment of a scalar volume over any number type: the
/// ramp vf → vb cut at the control values (as for_each_ramp_piece), each
/// piece integrated by integrate_piece_t, composed as RampIntegral.
/// sigma_at(k) and color_at(k, c) give control point k's values as S.
template <Model M, class S, class SigmaAt, class ColorAt>
preint::PieceIntegralT<S> ramp_t(const Classifier& tf, const S& vf, const S& vb, double delta, bool full,
                                 SigmaAt&& sigma_at, ColorAt&& color_at) {
    const auto& sig = tf.sigma_function();
    const auto& col = tf.color_function();
    preint::PieceIntegralT<S> out;  // depth, radiance E
    S T = 1.0;
    auto on_sigma = [&](std::size_t p, const S& v) -> S {
        const auto& kn = sig.knots();
        if (p == 0) return sigma_at(0);
        if (p >= kn.size()) return sigma_at(kn.size() - 1);
        const std::size_t k = p - 1;
        const S w = piece_position(v, kn[k], sig.inverse_widths()[k]);
        return sigma_at(k) + w * (sigma_at(k + 1) - sigma_at(k));
    };
    auto on_color = [&](std::size_t p, const S& v) -> std::array<S, 3> {
        const auto& kn = col.knots();
        std::array<S, 3> r;
        if (p == 0 || p >= kn.size()) {
            const std::size_t k = p == 0 ? 0 : kn.size() - 1;
            for (int c = 0; c < 3; ++c) r[c] = color_at(k, c);
            return r;
        }
        const std::size_t k = p - 1;
        const S w = piece_position(v, kn[k], col.inverse_widths()[k]);
        for (int c = 0; c < 3; ++c) r[c] = color_at(k, c) + w * (color_at(k + 1, c) - color_at(k, c));
        return r;
    };
    auto piece = [&](const S& l0, const S& l1) {
        const S v0 = vf + l0 * (vb - vf), v1 = vf + l1 * (vb - vf);
        const double vm = 0.5 * (value_of(v0) + value_of(v1));
        const std::size_t ps = sig.piece(vm), pc = col.piece(vm);
        S s0 = on_sigma(ps, v0), s1 = on_sigma(ps, v1);
        const auto c0 = on_color(pc, v0), c1 = on_color(pc, v1);
        preint::QuadraticT<S> q =
            tf.associated() ? preint::emission_source(c0, c1) : preint::particle_source(s0, s1, c0, c1);
        if constexpr (M == Model::absorption) q = {};
        if constexpr (M == Model::emission) s0 = s1 = S(0.0);
        const auto r = preint::integrate_piece_t<S>((l1 - l0) * delta, s0, s1, q, full);
        for (int k = 0; k < 3; ++k) out.radiance[k] += (full ? T : S(1.0)) * r.radiance[k];
        out.depth += r.depth;
        T = exp(-out.depth);
    };
    using std::exp;
    const auto& knots = tf.breakpoints();
    S l = 0.0;
    const double f = value_of(vf), b = value_of(vb);
    if (f < b) {
        for (auto it = std::upper_bound(knots.begin(), knots.end(), f); it != knots.end() && *it < b; ++it) {
            const S ln = (*it - vf) / (vb - vf);
            piece(l, ln);
            l = ln;
        }
    } else if (b < f) {
        auto it = std::lower_bound(knots.begin(), knots.end(), f);
        while (it != knots.begin() && *(it - 1) > b) {
            --it;
            const S ln = (vf - *it) / (vf - vb);
            piece(l, ln);
            l = ln;
        }
    }
    piece(l, S(1.0));
    return out;
}

template <Model M, class T>
struct PreintScalarSegments {
    const ScalarMed<T>& med;
    SampleGrid grid;
    double delta;
    bool full;
    Gradients* g = nullptr;

    SegmentValue value(std::int64_t i) const {
        const double vf = med.grid(grid.at(i - 1)), vb = med.grid(grid.at(i));
        const Segment s = preintegrate_scalar<M>(*med.tf, vf, vb, delta, full);
        return {s.transmittance, s.radiance};
    }

    static constexpr int kSlots = 16;
    using S = Dual<kSlots>;

    void grad(std::int64_t i, const SegmentAdjoint& a) const {
        const GridCell cf = med.grid.cell(grid.at(i - 1)), cb = med.grid.cell(grid.at(i));
        const double vf = med.grid.interpolate(cf), vb = med.grid.interpolate(cb);
        const auto& sig = med.tf->sigma_function();
        const auto& col = med.tf->color_function();
        // The control points this ramp reads: σ points and color points.
        std::vector<std::pair<bool, std::size_t>> used;  // (is color, index)
        {
            const double lo = std::min(vf, vb), hi = std::max(vf, vb);
            auto add_range = [&](const std::vector<double>& kn, bool is_color) {
                if (kn.empty()) return;
                // Pieces touched: piece(lo) .. piece(hi); piece p reads points p−1, p (clamped).
                const std::size_t p0 = is_color ? col.piece(lo) : sig.piece(lo);
                const std::size_t p1 = is_color ? col.piece(hi) : sig.piece(hi);
                const std::size_t k0 = p0 == 0 ? 0 : p0 - 1, k1 = std::min(p1, kn.size() - 1);
                for (std::size_t k = k0; k <= k1; ++k) used.push_back({is_color, k});
            };
            add_range(sig.knots(), false);
            add_range(col.knots(), true);
        }
        std::vector<int> slot_sigma(sig.knots().size(), -1), slot_color(col.knots().size(), -1);
        double dvf = 0, dvb = 0;
        std::size_t next = 0;
        bool first = true;
        while (first || next < used.size()) {
            std::fill(slot_sigma.begin(), slot_sigma.end(), -1);
            std::fill(slot_color.begin(), slot_color.end(), -1);
            int slot = 2;  // 0: vf, 1: vb
            const std::size_t begin = next;
            while (next < used.size()) {
                const int need = used[next].first ? 3 : 1;
                if (slot + need > kSlots) break;
                (used[next].first ? slot_color : slot_sigma)[used[next].second] = slot;
                slot += need;
                ++next;
            }
            const S sf = first ? S::variable(vf, 0) : S(vf), sb = first ? S::variable(vb, 1) : S(vb);
            auto sigma_at = [&](std::size_t k) {
                const double x = sig.values()[k][0];
                return slot_sigma[k] >= 0 ? S::variable(x, slot_sigma[k]) : S(x);
            };
            auto color_at = [&](std::size_t k, int c) {
                const double x = col.values()[k][c];
                return slot_color[k] >= 0 ? S::variable(x, slot_color[k] + c) : S(x);
            };
            const auto r = ramp_t<M, S>(*med.tf, sf, sb, delta, full, sigma_at, color_at);
            auto d = [&](int k) {
                double x = a.tau * r.depth.d[k];
                for (int c = 0; c < 3; ++c) x += a.radiance[c] * r.radiance[c].d[k];
                return x;
            };
            if (first) {
                dvf = d(0);
                dvb = d(1);
            }
            for (std::size_t u = begin; u < next; ++u) {
                const std::size_t k = used[u].second;
                if (used[u].first) {
                    for (int c = 0; c < 3; ++c) g->tf_color[k][c] += d(slot_color[k] + c);
                } else {
                    g->tf_alpha[k] += d(slot_sigma[k]) * (*med.alpha_chain)[k];
                }
            }
            first = false;
        }
        med.scatter_scalar(cf, dvf, *g);
        med.scatter_scalar(cb, dvb, *g);
    }
};

}  // namespace

// ------------------------------------------------------------- renderer ---

namespace {

/// Zero gradients with the sizes of g.
Gradients sized_like(const Gradients& g) {
    Gradients r;
    r.density.assign(g.density.size(), 0.0);
    r.color.assign(g.color.size(), 0.0);
    r.scalar.assign(g.scalar.size(), 0.0);
    r.tf_alpha.assign(g.tf_alpha.size(), 0.0);
    r.tf_color.assign(g.tf_color.size(), Rgb{0, 0, 0});
    return r;
}

bool same_sizes(const Gradients& a, const Gradients& b) {
    return a.density.size() == b.density.size() && a.color.size() == b.color.size() &&
           a.scalar.size() == b.scalar.size() && a.tf_alpha.size() == b.tf_alpha.size() &&
           a.tf_color.size() == b.tf_color.size();
}

/// b[i] += a[i]; a[i] = 0 over [lo, hi) of a's size.
void add_and_zero(std::vector<double>& into, std::vector<double>& from, std::size_t lo, std::size_t hi) {
    hi = std::min(hi, from.size());
    for (std::size_t i = lo; i < hi; ++i) {
        into[i] += from[i];
        from[i] = 0.0;
    }
}

}  // namespace

/// Zeroed gradient buffers kept between calls (the per-thread buffers of
/// the batched backward passes): allocating and clearing them each call cost
/// as much as the rays on large grids.
struct ScratchPool {
    std::mutex m;
    std::vector<std::unique_ptr<Gradients>> free;

    std::unique_ptr<Gradients> take(const Gradients& like) {
        {
            std::lock_guard lock(m);
            for (auto& p : free)
                if (same_sizes(*p, like)) {
                    std::unique_ptr<Gradients> r = std::move(p);
                    free.erase(std::find(free.begin(), free.end(), nullptr));
                    return r;
                }
        }
        return std::make_unique<Gradients>(sized_like(like));
    }
    void give(std::unique_ptr<Gradients> p) {  // p must be zero
        std::lock_guard lock(m);
        free.push_back(std::move(p));
        if (free.size() > 8) free.erase(free.begin());
    }
};

struct DiffRenderer::Impl {
    Renderer::Impl base;  // settings, lattice, spans, step, background, classifier
    const Volume* density = nullptr;
    const Volume* color = nullptr;
    const Volume* scalar = nullptr;
    std::size_t alpha_points = 0, color_points = 0;
    std::vector<double> alpha_chain;  // dσ_k/d(written value_k)
    bool skip = false;                // skip_empty_density: base.empty_space holds the macrocells
    mutable ScratchPool scratch;      // per-thread buffers of the batched backward passes

    /// Calls f(seg, n) with the segment walker of the ray and its count n, or
    /// returns false when the ray misses.
    template <class F>
    bool with_segments(const Ray& ray, double offset, Gradients* g, F&& f) const {
        RaySpan span;
        if (!base.span_of(ray, span)) return false;
        span.sample_offset = offset;
        const RenderSettings& s = base.s;
        const std::int64_t n = segment_count(span.length(), base.h);
        const double delta = span.length() / static_cast<double>(n);
        const double off = point_offset(s.sample_point, span.sample_offset);
        const SampleGrid point{&span, delta, off, 1};
        const SampleGrid ends{&span, delta, 0.0, 0};
        const bool full = s.integrator == IntegratorKind::preintegrated;
        auto run = [&]<Model M>() {
            if (scalar != nullptr) {
                visit_dtype(scalar->dtype(), [&]<class T>(T*) {
                    ScalarMed<T> med{GridSampler<T>(*scalar), &base.tf, &alpha_chain};
                    dispatch<M>(med, point, ends, delta, full, n, g, f, PreintScalarTag{});
                });
            } else {
                visit_dtype(density->dtype(), [&]<class D>(D*) {
                    if constexpr (std::is_floating_point_v<D>) {
                        visit_dtype(color->dtype(), [&]<class C>(C*) {
                            if constexpr (std::is_floating_point_v<C>) {
                                GridMed<D, C> med{GridSampler<D>(*density), GridSampler<C>(*color)};
                                dispatch<M>(med, point, ends, delta, full, n, g, f, PreintGridTag{});
                            }
                        });
                    }
                });
            }
        };
        switch (s.model) {
            case Model::absorption:
                run.template operator()<Model::absorption>();
                break;
            case Model::emission:
                run.template operator()<Model::emission>();
                break;
            default:
                run.template operator()<Model::emission_absorption>();
                break;
        }
        return true;
    }

    struct PreintScalarTag {};
    struct PreintGridTag {};

    template <Model M, class Med, class F, class Tag>
    void dispatch(const Med& med, const SampleGrid& point, const SampleGrid& ends, double delta, bool full,
                  std::int64_t n, Gradients* g, F& f, Tag) const {
        // Skipping (pre-classified grids, when asked for): runs of samples (point-sampled) or of
        // segments with both ends (pre-integrated) in one macrocell.
        const bool point_sampled =
            base.s.integrator == IntegratorKind::riemann || base.s.integrator == IntegratorKind::alpha;
        std::optional<RunFinder> finder;
        if (skip) finder.emplace(base.empty_space, point_sampled ? point : ends);
        const MacrocellRuns runs{n, finder ? &*finder : nullptr, !point_sampled};
        switch (base.s.integrator) {
            case IntegratorKind::riemann: {
                PointSegments<M, false, Med> seg{med, point, delta, g};
                f(seg, n, runs);
                return;
            }
            case IntegratorKind::alpha: {
                PointSegments<M, true, Med> seg{med, point, delta, g};
                f(seg, n, runs);
                return;
            }
            default:
                if constexpr (std::is_same_v<Tag, PreintScalarTag>) {
                    PreintScalarSegments<M, std::remove_cvref_t<decltype(*med.grid.data)>> seg{
                        med, ends, delta, full, g};
                    f(seg, n, runs);
                } else {
                    PreintGridSegments<M, std::remove_cvref_t<decltype(*med.density.data)>,
                                       std::remove_cvref_t<decltype(*med.color.data)>>
                        seg{med, ends, delta, full, g};
                    f(seg, n, runs);
                }
                return;
        }
    }

    [[nodiscard]] double termination() const {
        return base.s.order == Order::front_to_back ? base.s.termination : 0.0;
    }

    [[nodiscard]] RayResult forward(const Ray& ray, double offset) const {
        RayResult r{base.bg, 0.0};
        with_segments(ray, offset, nullptr, [&](auto& seg, std::int64_t n, const MacrocellRuns& runs) {
            r = march_forward(n, termination(), base.bg, seg, runs);
        });
        return r;
    }
    /// Throws unless g has this renderer's sizes (a scalar volume's voxel
    /// gradient may be empty: not wanted).
    void check_sizes(const Gradients& g) const {
        bool ok = true;
        if (scalar != nullptr) {
            const auto n = static_cast<std::size_t>(scalar->num_nodes());
            ok = (g.scalar.empty() || g.scalar.size() == n) && g.tf_alpha.size() == alpha_points &&
                 g.tf_color.size() == color_points;
        } else {
            const auto n = static_cast<std::size_t>(density->num_nodes());
            ok = g.density.size() == n && g.color.size() == 3 * n;
        }
        if (!ok)
            throw Error("backward", "the gradients do not have this renderer's sizes (use make_gradients)");
    }
    void backward(const Ray& ray, const RayResult& fwd, const RayAdjoint& adj, Gradients& g,
                  double offset) const {
        with_segments(ray, offset, &g, [&](auto& seg, std::int64_t n, const MacrocellRuns& runs) {
            march_backward(n, termination(), fwd, adj, seg, runs);
        });
    }
    [[nodiscard]] int threads(std::size_t work) const {
        return static_cast<int>(
            std::clamp<std::size_t>(work, 1, static_cast<std::size_t>(resolve_threads(base.s.threads))));
    }
};

namespace {

void check_differentiable(const RenderSettings& s) {
    switch (s.model) {
        case Model::emission_absorption:
        case Model::absorption:
        case Model::emission:
            break;
        default:
            throw Error("differentiable rendering",
                        "model '" + std::string(to_string(s.model)) +
                            "' is not differentiable (emission-absorption, absorption or emission)");
    }
    if (s.integrator == IntegratorKind::reference)
        throw Error("differentiable rendering",
                    "the reference integrator is not differentiable (riemann, alpha, preintegrated, "
                    "preintegrated-simple)");
    if (s.shading.enabled) throw Error("differentiable rendering", "shading is not differentiable");
}

}  // namespace

DiffRenderer::DiffRenderer(const Volume& density, const Volume& color, RenderSettings settings)
    : impl_(std::make_unique<Impl>()) {
    check_differentiable(settings);
    // The renderer's own checks of the grids (types, components, lattice).
    (void)Renderer(density, color, [&] {
        RenderSettings s = settings;
        s.skip_empty = false;
        return s;
    }());
    impl_->base.s = settings;
    setup_lattice(impl_->base, density);
    impl_->density = &density;
    impl_->color = &color;
}

DiffRenderer::DiffRenderer(const Volume& volume, const TransferFunction& tf, RenderSettings settings)
    : impl_(std::make_unique<Impl>()) {
    check_differentiable(settings);
    check_lattice(volume, "volume");
    if (volume.components() != 1)
        throw Error("volume",
                    "a scalar volume needs 1 component, this one has " + std::to_string(volume.components()));
    if (!tf.gradient_opacity_points.empty())
        throw Error("differentiable rendering", "gradient opacity is not differentiable");
    if (tf.alpha_points.empty() || tf.color_points.empty())
        throw Error("transfer function", "needs alpha and color points");
    impl_->base.s = settings;
    setup_lattice(impl_->base, volume);
    const double u = tf.opacity_unit_distance.value_or(volume.smallest_spacing());
    impl_->base.tf = Classifier(tf, volume.smallest_spacing());
    impl_->scalar = &volume;
    impl_->alpha_points = tf.alpha_points.size();
    impl_->color_points = tf.color_points.size();
    for (const auto& [v, a] : tf.alpha_points) {
        (void)v;
        if (tf.alpha_kind == TransferFunction::Alpha::extinction)
            impl_->alpha_chain.push_back(1.0);
        else  // σ = −ln(1 − a)/u, clamped at a = 1 − 1e−6
            impl_->alpha_chain.push_back(a < 1.0 - 1e-6 ? 1.0 / (u * (1.0 - a)) : 0.0);
    }
}

DiffRenderer::~DiffRenderer() = default;
DiffRenderer::DiffRenderer(DiffRenderer&&) noexcept = default;
DiffRenderer& DiffRenderer::operator=(DiffRenderer&&) noexcept = default;

void DiffRenderer::skip_empty_density(bool on) {
    if (!on) {
        impl_->skip = false;
        impl_->base.empty_space = {};
        return;
    }
    if (impl_->density == nullptr)
        throw Error("differentiable rendering", "skipping empty density needs pre-classified grids");
    skip_empty_where(*impl_->density);
}

void DiffRenderer::skip_empty_where(const Volume& occupied) {
    if (impl_->density == nullptr)
        throw Error("differentiable rendering", "skipping empty density needs pre-classified grids");
    if (occupied.dims() != impl_->density->dims() || occupied.components() != 1)
        throw Error("differentiable rendering",
                    "the occupancy grid must be the density's lattice, one component");
    impl_->skip = false;
    impl_->base.empty_space = {};
    const IntegratorKind k = impl_->base.s.integrator;
    // 4³ for point samples, 8³ for segments (the pruned blocks are 4³ cells;
    // docs/reverse-rendering.md)
    const int shift = k == IntegratorKind::riemann || k == IntegratorKind::alpha ? 2 : 3;
    impl_->base.empty_space = EmptySpace::for_zeros(occupied, shift, impl_->base.s.threads);
    impl_->skip = impl_->base.empty_space.any();
}

double DiffRenderer::empty_fraction() const {
    return impl_->skip ? impl_->base.empty_space.empty_fraction() : 0.0;
}

const RenderSettings& DiffRenderer::settings() const {
    return impl_->base.s;
}

Gradients DiffRenderer::make_gradients() const {
    Gradients g;
    if (impl_->scalar != nullptr) {
        g.scalar.assign(static_cast<std::size_t>(impl_->scalar->num_nodes()), 0.0);
        g.tf_alpha.assign(impl_->alpha_points, 0.0);
        g.tf_color.assign(impl_->color_points, Rgb{0, 0, 0});
    } else {
        const auto n = static_cast<std::size_t>(impl_->density->num_nodes());
        g.density.assign(n, 0.0);
        g.color.assign(3 * n, 0.0);
    }
    return g;
}

RayResult DiffRenderer::forward(const Ray& ray, double sample_offset) const {
    return impl_->forward(ray, sample_offset);
}

void DiffRenderer::backward(const Ray& ray, const RayResult& forward, const RayAdjoint& adjoint, Gradients& g,
                            double sample_offset) const {
    impl_->check_sizes(g);
    impl_->backward(ray, forward, adjoint, g, sample_offset);
}

namespace {

/// Per-thread gradient buffers: thread 0 adds into g itself, the others
/// into zeroed buffers of g's sizes (from the pool), added to g in thread
/// order at the end (the additions of each element in that order: the same
/// result whichever way the reduction is split over threads).
class ThreadBuffers {
public:
    ThreadBuffers(Gradients& g, int threads, ScratchPool& pool) : g_(g), pool_(pool) {
        for (int t = 1; t < threads; ++t) part_.push_back(pool.take(g));
    }
    ThreadBuffers(const ThreadBuffers&) = delete;
    ThreadBuffers& operator=(const ThreadBuffers&) = delete;
    ~ThreadBuffers() {
        for (auto& p : part_) {
            if (!reduced_) p->zero();  // (an exception left them dirty)
            pool_.give(std::move(p));
        }
    }
    Gradients& operator[](int t) { return t == 0 ? g_ : *part_[static_cast<std::size_t>(t - 1)]; }
    /// Adds the buffers into g and zeroes them; the big arrays split over `threads`.
    template <class Parallel>
    void reduce(int threads, Parallel&& parallel) {
        if (part_.empty()) return;
        // Nodes: density (color: 3 per node) or scalar.
        const std::size_t n = g_.density.empty() ? g_.scalar.size() : g_.density.size();
        parallel(n, threads, [&](std::size_t b, std::size_t e, int) {
            for (auto& p : part_) {
                add_and_zero(g_.density, p->density, b, e);
                add_and_zero(g_.color, p->color, 3 * b, 3 * e);
                add_and_zero(g_.scalar, p->scalar, b, e);
            }
        });
        for (auto& p : part_) {
            add_and_zero(g_.tf_alpha, p->tf_alpha, 0, p->tf_alpha.size());
            for (std::size_t i = 0; i < p->tf_color.size(); ++i)
                for (int c = 0; c < 3; ++c) {
                    g_.tf_color[i][c] += p->tf_color[i][c];
                    p->tf_color[i][c] = 0.0;
                }
        }
        reduced_ = true;
    }

private:
    Gradients& g_;
    ScratchPool& pool_;
    std::vector<std::unique_ptr<Gradients>> part_;
    bool reduced_ = false;
};

void check_offsets(std::span<const Ray> rays, std::span<const double> offsets) {
    if (!offsets.empty() && offsets.size() != rays.size())
        throw Error("differentiable rendering", "rays and sample offsets differ in number");
}

}  // namespace

std::vector<RayResult> DiffRenderer::forward(std::span<const Ray> rays,
                                             std::span<const double> offsets) const {
    check_offsets(rays, offsets);
    std::vector<RayResult> out(rays.size());
    parallel_blocks(rays.size(), impl_->threads(rays.size()), [&](std::size_t b, std::size_t e, int) {
        for (std::size_t i = b; i < e; ++i)
            out[i] = impl_->forward(rays[i], offsets.empty() ? -1.0 : offsets[i]);
    });
    return out;
}

void DiffRenderer::backward(std::span<const Ray> rays, std::span<const RayResult> forward,
                            std::span<const RayAdjoint> adjoints, Gradients& g,
                            std::span<const double> offsets) const {
    check_offsets(rays, offsets);
    impl_->check_sizes(g);
    if (forward.size() != rays.size() || adjoints.size() != rays.size())
        throw Error("backward", "rays, forward results and adjoints differ in number");
    const int nt = impl_->threads(rays.size());
    ThreadBuffers buf(g, nt, impl_->scratch);
    parallel_blocks(rays.size(), nt, [&](std::size_t b, std::size_t e, int t) {
        for (std::size_t i = b; i < e; ++i)
            impl_->backward(rays[i], forward[i], adjoints[i], buf[t], offsets.empty() ? -1.0 : offsets[i]);
    });
    buf.reduce(nt, [&](std::size_t n, int threads, auto&& f) { parallel_blocks(n, threads, f); });
}

Image DiffRenderer::render(const Camera& camera) const {
    const RenderSettings& s = impl_->base.s;
    Image img(s.width, s.height);
    const auto count = static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height);
    parallel_blocks(count, impl_->threads(count), [&](std::size_t b, std::size_t e, int) {
        for (std::size_t k = b; k < e; ++k) {
            const int x = static_cast<int>(k % static_cast<std::size_t>(s.width));
            const int y = static_cast<int>(k / static_cast<std::size_t>(s.width));
            const double off = s.jitter ? jitter_offset(x, y, s.jitter_seed) : -1.0;
            const RayResult r = impl_->forward(camera.generate(x, y, s.width, s.height), off);
            float* p = img.pixel(x, y);
            for (int c = 0; c < 3; ++c) p[c] = static_cast<float>(r.radiance[c]);
            p[3] = static_cast<float>(r.alpha);
        }
    });
    return img;
}

void DiffRenderer::backward(const Camera& camera, std::span<const float> adjoint, Gradients& g) const {
    const RenderSettings& s = impl_->base.s;
    const auto count = static_cast<std::size_t>(s.width) * static_cast<std::size_t>(s.height);
    if (adjoint.size() != 4 * count)
        throw Error("backward", "the adjoint image must hold 4 floats per pixel (" +
                                    std::to_string(4 * count) + "), got " + std::to_string(adjoint.size()));
    impl_->check_sizes(g);
    const int nt = impl_->threads(count);
    ThreadBuffers buf(g, nt, impl_->scratch);
    parallel_blocks(count, nt, [&](std::size_t b, std::size_t e, int t) {
        for (std::size_t k = b; k < e; ++k) {
            const float* a = &adjoint[4 * k];
            if (a[0] == 0.0f && a[1] == 0.0f && a[2] == 0.0f && a[3] == 0.0f) continue;
            const int x = static_cast<int>(k % static_cast<std::size_t>(s.width));
            const int y = static_cast<int>(k / static_cast<std::size_t>(s.width));
            const double off = s.jitter ? jitter_offset(x, y, s.jitter_seed) : -1.0;
            const Ray ray = camera.generate(x, y, s.width, s.height);
            const RayResult fwd = impl_->forward(ray, off);  // in double, as the backward march needs
            impl_->backward(ray, fwd, {{a[0], a[1], a[2]}, a[3]}, buf[t], off);
        }
    });
    buf.reduce(nt, [&](std::size_t n, int threads, auto&& f) { parallel_blocks(n, threads, f); });
}

}  // namespace fathom
