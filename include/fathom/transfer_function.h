// Transfer functions (SPEC §3, docs/theory.md eq. (19)): a scalar v maps to
// an extinction σ(v) ≥ 0 (1/world unit, piecewise linear between control
// points) and to a non-associated color c(v) (source g = σ·c) or an
// associated emission q(v) (g = q).
#pragma once

#include <algorithm>
#include <array>
#include <filesystem>
#include <optional>
#include <string>
#include <string_view>
#include <utility>
#include <vector>

#include "fathom/math.h"

namespace fathom {

/// A piecewise-linear function of v with N components, given by control
/// points sorted by v. Points sharing one v make a jump: the first is the
/// left limit, from that v on the last holds. Beyond the ends the end values
/// hold (eq. (19)).
template <int N>
class PiecewiseLinear {
public:
    using Value = std::array<double, N>;

    PiecewiseLinear() = default;
    /// Points must be sorted by v (checked by the parsers, not here).
    explicit PiecewiseLinear(std::vector<std::pair<double, Value>> points);

    [[nodiscard]] Value operator()(double v) const { return on_piece(piece(v), v); }
    /// The linear piece holding v: the number of knots ≤ v (0: before the
    /// first knot, size(): after the last; both constant).
    [[nodiscard]] std::size_t piece(double v) const;
    /// Piece p's linear function at v (no search; exact at the piece's first
    /// end, between its two values everywhere, so one-sided limits at a jump
    /// come from choosing the piece): y_k + w·(y_{k+1} − y_k) with the position
    /// w = (v − v_k)·(1/(v_{k+1} − v_k)) (piece_position).
    [[nodiscard]] Value on_piece(std::size_t p, double v) const;
    [[nodiscard]] const std::vector<double>& knots() const { return v_; }
    /// 1/(v_{k+1} − v_k) per knot k (0 for the last, and +∞ between duplicate
    /// knots, which no piece selects): on_piece multiplies by it instead of
    /// dividing, and so do the SIMD lanes and the differentiable renderer.
    [[nodiscard]] const std::vector<double>& inverse_widths() const { return inv_; }
    [[nodiscard]] const std::vector<Value>& values() const { return y_; }
    [[nodiscard]] bool empty() const { return v_.empty(); }
    /// True when every piece that values in [a, b] select has both of its
    /// defining values exactly 0 in every component, so that the function
    /// (and each one-sided limit) is exactly 0 wherever it is evaluated on
    /// [a, b]. Conservative: false for NaN bounds or an empty function.
    [[nodiscard]] bool zero_on(double a, double b) const;

private:
    std::vector<double> v_;
    std::vector<Value> y_;
    std::vector<double> inv_;                           // inverse_widths
    std::vector<std::pair<double, double>> zero_runs_;  // [start, end) where every piece is 0
};

/// The position w ∈ [0, 1] of v on a piece [k0, k1) from knot k0 with
/// inv = 1/(k1 − k0) rounded: (v − k0)·inv. It stays ≤ 1, so the value stays
/// between the piece's two (σ ≥ 0): v < k1 rounds v − k0 to no more than
/// d = k1 − k0 rounded, and d·inv = 1 + e with |e| ≤ 2⁻⁵³ rounds to 1 at
/// most (a tie goes to the even 1). S: double, or a number type of the
/// differentiable renderer.
template <class S>
inline S piece_position(const S& v, double k0, double inv) {
    return (v - k0) * inv;
}

// Inline: these run once or twice per sample.
template <int N>
inline std::size_t PiecewiseLinear<N>::piece(double v) const {
    // Linear scan for the short functions transfer functions are (fewer
    // mispredicted branches than a binary search), bisection beyond.
    if (v_.size() <= 8) {
        std::size_t p = 0;
        while (p < v_.size() && v_[p] <= v) ++p;
        return p;
    }
    return static_cast<std::size_t>(std::upper_bound(v_.begin(), v_.end(), v) - v_.begin());
}

template <int N>
inline typename PiecewiseLinear<N>::Value PiecewiseLinear<N>::on_piece(std::size_t p, double v) const {
    // Piece p lies between knot p−1 (the last point at its v: at a jump the
    // last one holds) and knot p, which is strictly larger.
    if (p == 0) return y_.front();
    if (p >= v_.size()) return y_.back();
    const std::size_t k = p - 1;
    const double w = piece_position(v, v_[k], inv_[k]);
    Value r;
    for (int c = 0; c < N; ++c) r[c] = y_[k][c] + w * (y_[k + 1][c] - y_[k][c]);
    return r;
}

/// The transfer function as written (fathom-tf/1). Opacity points keep their
/// opacity until the unit distance is known (it defaults to the volume's
/// smallest spacing); classify() turns it into σ.
struct TransferFunction {
    enum class Alpha { opacity, extinction };

    std::string name;
    Alpha alpha_kind = Alpha::opacity;
    std::vector<std::pair<double, double>> alpha_points;  // (v, a) or (v, σ)
    std::optional<double> opacity_unit_distance;          // only with Alpha::opacity
    bool associated = false;                              // true: "emission" (q); false: "color" (c)
    std::vector<std::pair<double, Rgb>> color_points;     // (v, rgb)
    /// Optional gradient opacity (VTK's): (|∇v|, f) points, |∇v| in scalar
    /// units per world unit, f ∈ [0, 1]; σ is multiplied by f(|∇v|). Empty:
    /// no modulation.
    std::vector<std::pair<double, double>> gradient_opacity_points;

    /// Parses fathom-tf/1 JSON text; errors name `subject` (the file).
    static TransferFunction from_json_text(std::string_view text, const std::string& subject);
    static TransferFunction from_file(const std::filesystem::path& path);
    /// A named preset. fathom's own (lower-case names) are written over [0, 1] and
    /// scaled to the value range [lo, hi] of the volume; 3D Slicer's (CT-Bone, ...)
    /// are in absolute units and ignore value_range. Names are case-sensitive.
    static TransferFunction preset(std::string_view name, std::array<double, 2> value_range);
    static std::vector<std::string> preset_names();

    /// Serialises as fathom-tf/1 JSON.
    [[nodiscard]] std::string to_json() const;
};

/// The integral functions of σ and of the source g over the scalar (Engel,
/// Kraus and Ertl's integral functions, docs/theory.md eqs. (15), (17)):
/// S(v) = ∫_{K₀}^v σ and G(v) = ∫_{K₀}^v g, K₀ the first breakpoint. Between
/// consecutive breakpoints σ and c are linear, so S is quadratic and G cubic
/// there. Row p serves the values with p breakpoints ≤ v: rows 0 and m (m
/// breakpoints) are the constant ends. Pre-integration without
/// self-attenuation takes a segment's integrals as differences of these.
struct IntegralFunctions {
    /// The columns, one value per row: the piece's start K, 1/width (0 at
    /// the ends), S and G at K, σ at K, half of σ's rise over the piece, and
    /// per channel g = A + B·w + C·w² (w ∈ [0, 1] over the piece) as A, B/2
    /// and C/3.
    enum Column : std::size_t {
        kStart,
        kInvWidth,
        kS,
        kSigma,
        kHalfRise,
        kG,
        kA = kG + 3,
        kB = kA + 3,
        kC = kB + 3,
        kColumns = kC + 3
    };
    std::vector<double> knots;  // the breakpoints
    /// Each column holds knots.size() + 1 rows, padded to a multiple of 8
    /// with the last row's values (for SIMD lane permutations).
    std::array<std::vector<double>, kColumns> col;

    [[nodiscard]] bool empty() const { return knots.empty(); }
    [[nodiscard]] std::size_t rows() const { return knots.size() + 1; }
    /// The row of v (PiecewiseLinear::piece over the breakpoints).
    [[nodiscard]] std::size_t row(double v) const {
        if (knots.size() <= 8) {
            std::size_t p = 0;
            while (p < knots.size() && knots[p] <= v) ++p;
            return p;
        }
        return static_cast<std::size_t>(std::upper_bound(knots.begin(), knots.end(), v) - knots.begin());
    }
    /// S(v) on row p.
    [[nodiscard]] double S(std::size_t p, double v) const {
        const double x = v - col[kStart][p], w = x * col[kInvWidth][p];
        return col[kS][p] + x * (col[kSigma][p] + col[kHalfRise][p] * w);
    }
    /// G(v) on row p.
    [[nodiscard]] Rgb G(std::size_t p, double v) const {
        const double x = v - col[kStart][p], w = x * col[kInvWidth][p];
        Rgb g;
        for (std::size_t k = 0; k < 3; ++k)
            g[k] = col[kG + k][p] + x * (col[kA + k][p] + w * (col[kB + k][p] + w * col[kC + k][p]));
        return g;
    }
};

/// The transfer function ready for evaluation: σ(v) and c(v) (or q(v)).
class Classifier {
public:
    Classifier() = default;
    /// default_unit_distance: used when the TF's opacity_unit_distance is absent.
    Classifier(const TransferFunction& tf, double default_unit_distance);

    [[nodiscard]] double sigma(double v) const { return sigma_(v)[0]; }
    /// c(v) for a "color" TF, q(v) for an "emission" TF.
    [[nodiscard]] Rgb color(double v) const { return color_(v); }
    /// The source g(v): σ(v)·c(v), or q(v) when associated.
    [[nodiscard]] Rgb source(double v) const {
        Rgb c = color_(v);
        if (!associated_) {
            const double s = sigma(v);
            for (double& x : c) x *= s;
        }
        return c;
    }
    [[nodiscard]] bool associated() const { return associated_; }
    /// σ is exactly 0 on [a, b] (PiecewiseLinear::zero_on).
    [[nodiscard]] bool sigma_zero_on(double a, double b) const { return sigma_.zero_on(a, b); }
    /// c (or q) is exactly 0 on [a, b].
    [[nodiscard]] bool color_zero_on(double a, double b) const { return color_.zero_on(a, b); }
    [[nodiscard]] const PiecewiseLinear<1>& sigma_function() const { return sigma_; }
    [[nodiscard]] const PiecewiseLinear<3>& color_function() const { return color_; }
    /// True when the TF has gradient-opacity points.
    [[nodiscard]] bool has_gradient_opacity() const { return !grad_opacity_.empty(); }
    /// The gradient-opacity factor f(|∇v|) (1 without gradient opacity).
    [[nodiscard]] double gradient_factor(double magnitude) const {
        return grad_opacity_.empty() ? 1.0 : grad_opacity_(magnitude)[0];
    }
    /// Every control value of σ and of the color, sorted, without duplicates:
    /// the v where σ(v) or g(v) may bend or jump.
    [[nodiscard]] const std::vector<double>& breakpoints() const { return breaks_; }
    /// S(v) = ∫σ and G(v) = ∫g over the breakpoints' pieces (empty without
    /// σ or color points).
    [[nodiscard]] const IntegralFunctions& integrals() const { return integrals_; }

private:
    void build_integrals();

    PiecewiseLinear<1> sigma_;
    PiecewiseLinear<3> color_;
    PiecewiseLinear<1> grad_opacity_;
    bool associated_ = false;
    std::vector<double> breaks_;
    IntegralFunctions integrals_;
};

/// Opacity a per unit distance u → extinction (eq. (19)).
double opacity_to_extinction(double a, double unit_distance);

}  // namespace fathom
