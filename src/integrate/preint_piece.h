// The integral over one pre-integration piece (σ_a linear, source
// quadratic), as a template over the number type: double for rendering, a
// dual number (src/diff/dual.h) for its derivatives with respect to the
// piece's parameters.
#pragma once

#include <algorithm>
#include <array>
#include <cmath>
#include <type_traits>

#include "diff/dual.h"
#include "integrate/exp_neg.h"
#include "integrate/preintegrated.h"

namespace fathom::preint {
namespace detail {

// 6-point Gauss–Legendre on [0, 1].
constexpr std::array<double, 6> kX{0.033765242898423975, 0.16939530676686776, 0.38069040695840156,
                                   0.61930959304159844,  0.83060469323313224, 0.96623475710157603};
constexpr std::array<double, 6> kW{0.085662246189585178, 0.18038078652406930, 0.23395696728634552,
                                   0.23395696728634552,  0.18038078652406930, 0.085662246189585178};
// 3-point Gauss–Legendre on [0, 1], for pieces of optical depth ≤ kThin:
// exact for degree 5, so the error is that of e^{−τ} past its τ³ term
// (< 1e−7 of the piece's radiance).
constexpr std::array<double, 3> kX3{0.11270166537925831, 0.5, 0.88729833462074169};
constexpr std::array<double, 3> kW3{0.27777777777777778, 0.44444444444444444, 0.27777777777777778};
constexpr double kThin = 0.25;
// Beyond this optical depth inside one piece the rest contributes < e^{−40}.
constexpr double kMaxDepth = 40.0;

template <class S>
std::array<S, 3> eval(const QuadraticT<S>& g, const S& u) {
    return {g.a[0] + u * (g.b[0] + u * g.c[0]), g.a[1] + u * (g.b[1] + u * g.c[1]),
            g.a[2] + u * (g.b[2] + u * g.c[2])};
}

/// e^{−x}: F for double (exp_neg, or exp_neg_thin where x ≤ kThin: the bits
/// SIMD lanes reproduce), std::exp otherwise.
template <class S, double (*F)(double) = exp_neg>
S exp_of_neg(const S& x) {
    if constexpr (std::is_same_v<S, double>) {
        return F(x);
    } else {
        using std::exp;
        return exp(-x);
    }
}

template <class S>
S min_of(const S& a, const S& b) {  // as std::min: a unless b < a
    return b < a ? b : a;
}

}  // namespace detail

/// integrate_piece over any number type. The double instance is
/// integrate_piece itself; other types skip the closed form of a constant
/// piece (exact only where the piece stays constant, so its derivative with
/// respect to s1 or the source's slope would be wrong) and take the
/// quadrature, which matches the closed form to about 1e−10.
template <class S>
PieceIntegralT<S> integrate_piece_t(const S& len, const S& s0, const S& s1, const QuadraticT<S>& g,
                                    bool self_attenuation) {
    using std::sqrt;
    using namespace detail;
    PieceIntegralT<S> r;
    r.depth = len * 0.5 * (s0 + s1);  // eq. (15)
    if (!self_attenuation) {          // eq. (17): len·∫₀¹ g du
        for (int k = 0; k < 3; ++k) r.radiance[k] = len * (g.a[k] + g.b[k] / 2 + g.c[k] / 3);
        return r;
    }
    if constexpr (std::is_same_v<S, double>) {
        const bool constant = s0 == s1 && g.b == Rgb{0, 0, 0} && g.c == Rgb{0, 0, 0};
        if (constant) {  // exact, as the alpha quadrature: g·(1 − e^{−σ len})/σ
            const double w = s0 > 0.0 ? one_minus_exp_neg(s0 * len) / s0 : len;
            for (int k = 0; k < 3; ++k) r.radiance[k] = g.a[k] * w;
            return r;
        }
    }
    // eq. (16): len·∫₀¹ g(u)·exp(−τ(u)) du with τ(u) = A u + B u²,
    // on sub-intervals of optical depth ≤ 1.
    const S A = len * s0, B = len * 0.5 * (s1 - s0);
    auto tau = [&](const S& u) { return u * (A + B * u); };
    auto u_at = [&](const S& level) -> S {  // τ(u) = level, u ∈ [0, 1] (τ increases)
        if (B == 0.0) return min_of<S>(1.0, level / A);
        S disc = A * A + 4.0 * B * level;
        if (!(0.0 < disc)) disc = 0.0;  // as std::max(0.0, disc)
        return min_of<S>(1.0, 2.0 * level / (A + sqrt(disc)));
    };
    if (r.depth <= kThin) {
        for (int q = 0; q < 3; ++q) {
            const auto gu = eval<S>(g, kX3[q]);
            const S w = len * kW3[q] * exp_of_neg<S, exp_neg_thin>(tau(kX3[q]));  // τ ≤ kThin
            for (int k = 0; k < 3; ++k) r.radiance[k] += w * gu[k];
        }
        return r;
    }
    const S total = min_of<S>(r.depth, kMaxDepth);
    const int chunks = std::max(1, static_cast<int>(std::ceil(value_of(total))));
    S u0 = 0.0;
    for (int m = 1; m <= chunks; ++m) {
        const S u1 = (m == chunks && r.depth <= kMaxDepth) ? S(1.0) : u_at(total * m / chunks);
        const S du = u1 - u0;
        for (int q = 0; q < 6; ++q) {
            const S u = u0 + du * kX[q];
            const auto gu = eval(g, u);
            const S w = len * du * kW[q] * exp_of_neg<S>(tau(u));
            for (int k = 0; k < 3; ++k) r.radiance[k] += w * gu[k];
        }
        u0 = u1;
    }
    return r;
}

}  // namespace fathom::preint
