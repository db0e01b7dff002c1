// e^{−x} and 1 − e^{−x} as the pre-integrated integrators evaluate them:
// one sequence of additions and multiplications that the scalar code and
// every SIMD lane (simd_preint.cpp) perform alike, so that both give the
// same bits.
//
// −x = k·ln 2 + r with k an integer and |r| ≤ ln 2 / 2 (Cody and Waite's
// two-part ln 2, so k·ln2_hi is exact); e^r by its Taylor series to degree
// 13 (truncation < 5e−18 relative) by Estrin's scheme, times 2^k built from
// its exponent bits. e^{−x} is within 2 ulp of libm's, 1 − e^{−x} within 4.
#pragma once

#include <array>
#include <bit>
#include <cmath>
#include <cstdint>

namespace fathom::preint {

namespace exp_detail {
inline constexpr double kInvLn2 = 1.44269504088896338700e+00;
inline constexpr double kLn2Hi = 6.93147180369123816490e-01;  // 32 significant bits
inline constexpr double kLn2Lo = 1.90821492927058770002e-10;
/// 1.5·2^52: adding and subtracting it rounds |x| < 2^51 to an integer
/// (no libm call, the same in every lane).
inline constexpr double kRound = 6755399441055744.0;
/// The range where the reduction above holds with a normal 2^k: beyond it
/// std::exp (underflow, overflow, NaN).
inline constexpr double kMinArg = -708.0, kMaxArg = 708.0;
inline constexpr std::size_t kDegree = 13;
/// 1/i! for i = 0 … kDegree + 1.
inline constexpr std::array<double, kDegree + 2> kTaylor = [] {
    std::array<double, kDegree + 2> c{};
    c[0] = 1.0;
    for (std::size_t i = 1; i < c.size(); ++i) c[i] = c[i - 1] / static_cast<double>(i);
    return c;
}();

/// Σ kTaylor[i + from]·r^i for i = 0 … kDegree by Estrin's scheme (a
/// quarter of Horner's latency): e^r for from = 0, (e^r − 1)/r for from = 1.
/// simd_preint.cpp's Taylor repeats these operations in this order (a
/// template shared with it would be compiled without its target's
/// instruction set).
inline double taylor_estrin(double r, std::size_t from) {
    auto pair = [&](std::size_t i) { return kTaylor[from + i] + kTaylor[from + i + 1] * r; };
    const double r2 = r * r, r4 = r2 * r2, r8 = r4 * r4;
    const double b0 = pair(0) + pair(2) * r2, b1 = pair(4) + pair(6) * r2;
    const double b2 = pair(8) + pair(10) * r2, b3 = pair(12);
    return (b0 + b1 * r4) + (b2 + b3 * r4) * r8;
}

/// The reduction: −x = k·ln 2 + r; false outside [kMinArg, kMaxArg] or NaN.
inline bool reduce(double x, double& k, double& r) {
    const double y = -x;
    if (!(y >= kMinArg && y <= kMaxArg)) return false;
    k = (y * kInvLn2 + kRound) - kRound;  // nearest integer, ties to even
    r = (y - k * kLn2Hi) - k * kLn2Lo;
    return true;
}

/// 2^k for an integer k in the reduction's range.
inline double two_to(double k) {
    return std::bit_cast<double>(static_cast<std::uint64_t>(static_cast<std::int64_t>(k) + 1023) << 52);
}
}  // namespace exp_detail

/// e^{−x}: the reduction above for −x in [−708, 708], std::exp beyond.
inline double exp_neg(double x) {
    using namespace exp_detail;
    double k, r;
    if (!reduce(x, k, r)) return std::exp(-x);
    return taylor_estrin(r, 0) * two_to(k);
}

/// e^{−x} for 0 ≤ x ≤ 1/4 (the nodes of pre-integration's thin pieces,
/// whose 3-node rule errs by up to 1e−7 anyway): the Taylor series to degree
/// 7 by Estrin's scheme, truncation < 4e−10 (x⁸/8! at 1/4); no reduction.
inline double exp_neg_thin(double x) {
    using exp_detail::kTaylor;
    const double r = -x;
    auto pair = [&](std::size_t i) { return kTaylor[i] + kTaylor[i + 1] * r; };
    const double r2 = r * r, r4 = r2 * r2;
    return (pair(0) + pair(2) * r2) + (pair(4) + pair(6) * r2) * r4;
}

/// 1 − e^{−x} (−expm1(−x)), to a few ulp also for tiny x: with
/// m = e^r − 1 = r·(e^r − 1)/r from its own series, 1 − 2^k·(1 + m) =
/// (1 − 2^k) − 2^k·m, where 1 − 2^k and the scaling are exact (k ≤ 0 for
/// x ≥ 0; −m where k = 0): one polynomial and no branch on k.
/// std::expm1 beyond the reduction.
inline double one_minus_exp_neg(double x) {
    using namespace exp_detail;
    double k, r;
    if (!reduce(x, k, r)) return -std::expm1(-x);
    const double scale = two_to(k);
    return (1.0 - scale) - scale * (r * taylor_estrin(r, 1));
}

}  // namespace fathom::preint
