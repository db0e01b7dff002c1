// `reference`: the continuous model of eq. (3) integrated adaptively to a
// stated accuracy (eq. (22)); the ground truth for convergence studies.
//
// The ray is cut where the integrand is not smooth: at cell boundaries (the
// trilinear interpolant's derivative jumps there) and, for a scalar volume,
// where v(t) crosses a transfer-function control value. On each piece σ_a(t)
// is a cubic polynomial (fitted exactly from four interior samples), so the
// optical depth is integrated in closed form; the radiance
// E = ∫ g(t)·exp(−∫_a^t σ_a) dt is integrated by adaptive Gauss–Legendre.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <vector>

#include "integrate/accumulator.h"
#include "integrate/ray_span.h"

namespace fathom {
namespace reference_detail {

/// A cubic in the local parameter s ∈ [0, 1] of a piece, fitted from values
/// at the interior nodes s = 1/8, 3/8, 5/8, 7/8 (never at the ends, where a
/// transfer-function jump would give the other side's value).
struct Cubic {
    std::array<double, 4> a{};  // a0 + a1 s + a2 s² + a3 s³

    static constexpr std::array<double, 4> kNodes{0.125, 0.375, 0.625, 0.875};
    static Cubic fit(const std::array<double, 4>& y);
    [[nodiscard]] double operator()(double s) const { return a[0] + s * (a[1] + s * (a[2] + s * a[3])); }
    /// ∫_0^s of the cubic.
    [[nodiscard]] double integral(double s) const {
        return s * (a[0] + s * (a[1] / 2 + s * (a[2] / 3 + s * a[3] / 4)));
    }
    /// Parameters in (0, 1) where the derivative vanishes, sorted.
    [[nodiscard]] std::vector<double> extrema() const;
};

/// Roots s in (s0, s1) of cubic(s) = target on a monotone interval (bisection).
double solve_monotone(const Cubic& c, double s0, double s1, double target);

/// 8-point Gauss–Legendre nodes and weights on [−1, 1].
inline constexpr std::array<double, 8> kGlX{-0.9602898564975363, -0.7966664774136267, -0.5255324099163290,
                                            -0.1834346424956498, 0.1834346424956498,  0.5255324099163290,
                                            0.7966664774136267,  0.9602898564975363};
inline constexpr std::array<double, 8> kGlW{0.1012285362903763, 0.2223810344533745, 0.3137066458778873,
                                            0.3626837833783620, 0.3626837833783620, 0.3137066458778873,
                                            0.2223810344533745, 0.1012285362903763};

}  // namespace reference_detail

template <Model M, class Medium>
class ReferenceIntegrator {
public:
    ReferenceIntegrator(const Medium& medium, const RaySpan& span, double tolerance,
                        const std::vector<double>* tf_breaks)
        : medium_(medium), span_(span), tol_(tolerance), breaks_(tf_breaks) {}

    RayResult run(const Rgb& bg) {
        std::vector<double> cuts = cell_cuts();
        for (std::size_t i = 0; i + 1 < cuts.size(); ++i) {
            if (!(cuts[i + 1] > cuts[i])) continue;
            if constexpr (Medium::kHasScalar) {
                integrate_cell(cuts[i], cuts[i + 1]);
            } else {
                integrate_piece(cuts[i], cuts[i + 1]);
            }
        }
        RayResult r;
        for (int c = 0; c < 3; ++c) r.radiance[c] = I_[c] + T_ * bg[c];
        r.alpha = 1.0 - T_;
        return r;
    }

private:
    using Cubic = reference_detail::Cubic;

    [[nodiscard]] MediumSample sample(double t) const {
        MediumSample m = medium_.at(span_.at(t));
        apply_model<M>(m.sigma, m.source);
        return m;
    }

    // t where the ray crosses an integer plane of the index space, plus both ends.
    [[nodiscard]] std::vector<double> cell_cuts() const {
        std::vector<double> cuts{span_.t_near, span_.t_far};
        for (int a = 0; a < 3; ++a) {
            if (span_.dp[a] == 0.0) continue;
            const double u0 = span_.p0[a] + span_.t_near * span_.dp[a];
            const double u1 = span_.p0[a] + span_.t_far * span_.dp[a];
            for (double k = std::floor(std::min(u0, u1)) + 1; k < std::max(u0, u1); k += 1.0) {
                const double t = (k - span_.p0[a]) / span_.dp[a];
                if (t > span_.t_near && t < span_.t_far) cuts.push_back(t);
            }
        }
        std::sort(cuts.begin(), cuts.end());
        return cuts;
    }

    // One cell: cut further where v(t) crosses a transfer-function control value.
    void integrate_cell(double ta, double tb) {
        std::array<double, 4> y{};
        for (int k = 0; k < 4; ++k) y[k] = medium_.scalar(span_.at(ta + Cubic::kNodes[k] * (tb - ta)));
        const Cubic v = Cubic::fit(y);
        std::vector<double> s_cuts{0.0};
        for (double e : v.extrema()) s_cuts.push_back(e);
        s_cuts.push_back(1.0);
        std::vector<double> cuts{0.0, 1.0};
        for (std::size_t m = 0; m + 1 < s_cuts.size(); ++m) {
            const double s0 = s_cuts[m], s1 = s_cuts[m + 1];
            cuts.push_back(s0);
            const double lo = std::min(v(s0), v(s1)), hi = std::max(v(s0), v(s1));
            auto it = std::upper_bound(breaks_->begin(), breaks_->end(), lo);
            for (; it != breaks_->end() && *it < hi; ++it)
                cuts.push_back(reference_detail::solve_monotone(v, s0, s1, *it));
        }
        std::sort(cuts.begin(), cuts.end());
        for (std::size_t i = 0; i + 1 < cuts.size(); ++i)
            if (cuts[i + 1] > cuts[i])
                integrate_piece(ta + cuts[i] * (tb - ta), ta + cuts[i + 1] * (tb - ta));
    }

    // A smooth piece [a, b]: σ_a is a cubic there.
    void integrate_piece(double a, double b) {
        if (!(b > a)) return;
        std::array<double, 4> y{};
        for (int k = 0; k < 4; ++k) y[k] = sample(a + Cubic::kNodes[k] * (b - a)).sigma;
        sigma_ = Cubic::fit(y);
        a_ = a;
        len_ = b - a;
        const double tol = std::max(1e-13, 0.1 * tol_ * (b - a) / span_.length());
        Rgb whole = gauss(a, b);
        const Rgb e = refine(a, b, whole, tol, 0);
        for (int c = 0; c < 3; ++c) I_[c] += T_ * e[c];
        T_ *= std::exp(-depth(a, b));
    }

    // Optical depth ∫_x^y σ_a over the current piece, in closed form.
    [[nodiscard]] double depth(double x, double y) const {
        return std::max(0.0, len_ * (sigma_.integral((y - a_) / len_) - sigma_.integral((x - a_) / len_)));
    }

    // ∫_x^y g(t)·exp(−∫_x^t σ_a) dt by 8-point Gauss–Legendre.
    [[nodiscard]] Rgb gauss(double x, double y) const {
        Rgb e{0, 0, 0};
        const double half = (y - x) / 2, mid = (x + y) / 2;
        for (int k = 0; k < 8; ++k) {
            const double t = mid + half * reference_detail::kGlX[k];
            const MediumSample m = sample(t);
            const double w = half * reference_detail::kGlW[k] * std::exp(-depth(x, t));
            for (int c = 0; c < 3; ++c) e[c] += w * m.source[c];
        }
        return e;
    }

    Rgb refine(double x, double y, const Rgb& whole, double tol, int level) const {
        const double m = (x + y) / 2;
        const Rgb l = gauss(x, m), r = gauss(m, y);
        const double tm = std::exp(-depth(x, m));
        Rgb split{};
        bool ok = true;
        for (int c = 0; c < 3; ++c) {
            split[c] = l[c] + tm * r[c];
            if (std::abs(split[c] - whole[c]) > tol * std::max(1.0, std::abs(split[c]))) ok = false;
        }
        if (ok || level >= 40) return split;
        const Rgb el = refine(x, m, l, tol / 2, level + 1), er = refine(m, y, r, tol / 2, level + 1);
        for (int c = 0; c < 3; ++c) split[c] = el[c] + tm * er[c];
        return split;
    }

    const Medium& medium_;
    RaySpan span_;
    double tol_;
    const std::vector<double>* breaks_;
    Cubic sigma_;
    double a_ = 0, len_ = 1;
    Rgb I_{0, 0, 0};
    double T_ = 1.0;
};

}  // namespace fathom
