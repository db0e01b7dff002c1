// Forward-mode dual numbers with N tangents: the derivatives of a segment's
// (optical depth, radiance) with respect to its few local parameters, taken
// through the very code that computes them (the pre-integrated piece
// integral is a template over its number type).
#pragma once

#include <array>
#include <cmath>

namespace fathom {

template <int N>
struct Dual {
    double v = 0;
    std::array<double, N> d{};

    Dual() = default;
    Dual(double x) : v(x) {}  // NOLINT: constants mix freely with duals
    /// The variable number `slot` with value x.
    static Dual variable(double x, int slot) {
        Dual r(x);
        r.d[static_cast<std::size_t>(slot)] = 1.0;
        return r;
    }

    friend Dual operator+(const Dual& a, const Dual& b) {
        Dual r(a.v + b.v);
        for (int i = 0; i < N; ++i) r.d[i] = a.d[i] + b.d[i];
        return r;
    }
    friend Dual operator-(const Dual& a, const Dual& b) {
        Dual r(a.v - b.v);
        for (int i = 0; i < N; ++i) r.d[i] = a.d[i] - b.d[i];
        return r;
    }
    friend Dual operator-(const Dual& a) {
        Dual r(-a.v);
        for (int i = 0; i < N; ++i) r.d[i] = -a.d[i];
        return r;
    }
    friend Dual operator*(const Dual& a, const Dual& b) {
        Dual r(a.v * b.v);
        for (int i = 0; i < N; ++i) r.d[i] = a.d[i] * b.v + a.v * b.d[i];
        return r;
    }
    friend Dual operator/(const Dual& a, const Dual& b) {
        Dual r(a.v / b.v);
        for (int i = 0; i < N; ++i) r.d[i] = (a.d[i] - r.v * b.d[i]) / b.v;
        return r;
    }
    Dual& operator+=(const Dual& b) { return *this = *this + b; }
    Dual& operator-=(const Dual& b) { return *this = *this - b; }
    Dual& operator*=(const Dual& b) { return *this = *this * b; }

    // Comparisons look at values only (branches of the computed function).
    friend bool operator<(const Dual& a, const Dual& b) { return a.v < b.v; }
    friend bool operator<=(const Dual& a, const Dual& b) { return a.v <= b.v; }
    friend bool operator>(const Dual& a, const Dual& b) { return a.v > b.v; }
    friend bool operator==(const Dual& a, const Dual& b) { return a.v == b.v; }
};

template <int N>
Dual<N> chain(const Dual<N>& a, double value, double derivative) {
    Dual<N> r(value);
    for (int i = 0; i < N; ++i) r.d[i] = derivative * a.d[i];
    return r;
}
template <int N>
Dual<N> exp(const Dual<N>& a) {
    const double e = std::exp(a.v);
    return chain(a, e, e);
}
template <int N>
Dual<N> expm1(const Dual<N>& a) {
    return chain(a, std::expm1(a.v), std::exp(a.v));
}
template <int N>
Dual<N> sqrt(const Dual<N>& a) {
    const double s = std::sqrt(a.v);
    return chain(a, s, s > 0.0 ? 0.5 / s : 0.0);
}

/// The value of a number or a dual.
inline double value_of(double x) {
    return x;
}
template <int N>
double value_of(const Dual<N>& x) {
    return x.v;
}

}  // namespace fathom
