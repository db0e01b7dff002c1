#include "integrate/reference.h"

namespace fathom::reference_detail {

Cubic Cubic::fit(const std::array<double, 4>& y) {
    // Newton's divided differences on the equally spaced nodes u = 0..3
    // (s = 1/8 + u/4), then expansion into monomials of s.
    const double d1 = y[1] - y[0];
    const double d2 = y[2] - 2 * y[1] + y[0];
    const double d3 = y[3] - 3 * y[2] + 3 * y[1] - y[0];
    // p(u) = y0 + d1 u + d2 u(u−1)/2 + d3 u(u−1)(u−2)/6
    const double c0 = y[0], c1 = d1 - d2 / 2 + d3 / 3, c2 = d2 / 2 - d3 / 2, c3 = d3 / 6;
    // u = 4s − 1/2 = α s + β
    const double al = 4.0, be = -0.5;
    Cubic r;
    r.a[0] = c0 + c1 * be + c2 * be * be + c3 * be * be * be;
    r.a[1] = c1 * al + 2 * c2 * al * be + 3 * c3 * al * be * be;
    r.a[2] = c2 * al * al + 3 * c3 * al * al * be;
    r.a[3] = c3 * al * al * al;
    return r;
}

std::vector<double> Cubic::extrema() const {
    // derivative: 3 a3 s² + 2 a2 s + a1
    const double A = 3 * a[3], B = 2 * a[2], C = a[1];
    std::vector<double> out;
    const double scale = std::abs(A) + std::abs(B) + std::abs(C);
    if (scale == 0.0) return out;
    if (std::abs(A) <= 1e-12 * scale) {
        if (B != 0.0) out.push_back(-C / B);
    } else {
        const double disc = B * B - 4 * A * C;
        if (disc >= 0) {
            const double q = -0.5 * (B + std::copysign(std::sqrt(disc), B));
            if (q != 0.0)
                out.push_back(q / A), out.push_back(C / q);
            else
                out.push_back(0.0);
        }
    }
    std::vector<double> in;
    for (double s : out)
        if (s > 0.0 && s < 1.0) in.push_back(s);
    std::sort(in.begin(), in.end());
    return in;
}

double solve_monotone(const Cubic& c, double s0, double s1, double target) {
    const bool increasing = c(s1) > c(s0);
    for (int it = 0; it < 60 && s1 - s0 > 1e-16; ++it) {
        const double m = 0.5 * (s0 + s1);
        if ((c(m) < target) == increasing)
            s0 = m;
        else
            s1 = m;
    }
    return 0.5 * (s0 + s1);
}

}  // namespace fathom::reference_detail
