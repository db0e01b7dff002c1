#include "integrate/preintegrated.h"

namespace fathom::preint {
namespace {

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

Rgb eval(const Quadratic& g, double u) {
    return {g.a[0] + u * (g.b[0] + u * g.c[0]), g.a[1] + u * (g.b[1] + u * g.c[1]),
            g.a[2] + u * (g.b[2] + u * g.c[2])};
}

}  // namespace

PieceIntegral integrate_piece(double len, double s0, double s1, const Quadratic& g, bool self_attenuation) {
    PieceIntegral r;
    r.depth = len * 0.5 * (s0 + s1);  // eq. (15)
    if (!self_attenuation) {          // eq. (17): len·∫₀¹ g du
        for (int k = 0; k < 3; ++k) r.radiance[k] = len * (g.a[k] + g.b[k] / 2 + g.c[k] / 3);
        return r;
    }
    const bool constant = s0 == s1 && g.b == Rgb{0, 0, 0} && g.c == Rgb{0, 0, 0};
    if (constant) {  // exact, as the alpha quadrature: g·(1 − e^{−σ len})/σ
        const double w = s0 > 0.0 ? -std::expm1(-s0 * len) / s0 : len;
        for (int k = 0; k < 3; ++k) r.radiance[k] = g.a[k] * w;
        return r;
    }
    // eq. (16): len·∫₀¹ g(u)·exp(−τ(u)) du with τ(u) = A u + B u²,
    // on sub-intervals of optical depth ≤ 1.
    const double A = len * s0, B = len * 0.5 * (s1 - s0);
    auto tau = [&](double u) { return u * (A + B * u); };
    auto u_at = [&](double level) {  // τ(u) = level, u ∈ [0, 1] (τ increases)
        if (B == 0.0) return std::min(1.0, level / A);
        const double disc = std::max(0.0, A * A + 4.0 * B * level);
        return std::min(1.0, 2.0 * level / (A + std::sqrt(disc)));
    };
    if (r.depth <= kThin) {
        for (int q = 0; q < 3; ++q) {
            const Rgb gu = eval(g, kX3[q]);
            const double w = len * kW3[q] * std::exp(-tau(kX3[q]));
            for (int k = 0; k < 3; ++k) r.radiance[k] += w * gu[k];
        }
        return r;
    }
    const double total = std::min(r.depth, kMaxDepth);
    const int chunks = std::max(1, static_cast<int>(std::ceil(total)));
    double u0 = 0.0;
    for (int m = 1; m <= chunks; ++m) {
        const double u1 = (m == chunks && r.depth <= kMaxDepth) ? 1.0 : u_at(total * m / chunks);
        const double du = u1 - u0;
        for (int q = 0; q < 6; ++q) {
            const double u = u0 + du * kX[q];
            const Rgb gu = eval(g, u);
            const double w = len * du * kW[q] * std::exp(-tau(u));
            for (int k = 0; k < 3; ++k) r.radiance[k] += w * gu[k];
        }
        u0 = u1;
    }
    return r;
}

}  // namespace fathom::preint
