// fathom-tf/1 parsing and evaluation (SPEC §3, docs/theory.md eq. (19)).
#include "fathom/transfer_function.h"

#include <algorithm>
#include <cmath>
#include <fstream>
#include <sstream>

#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/tf_interchange.h"

#include "tf/tf_json.h"

namespace fathom {

template <int N>
PiecewiseLinear<N>::PiecewiseLinear(std::vector<std::pair<double, Value>> points) {
    v_.reserve(points.size());
    y_.reserve(points.size());
    for (auto& [v, y] : points) {
        v_.push_back(v);
        y_.push_back(y);
    }
    inv_.assign(v_.size(), 0.0);
    for (std::size_t k = 0; k + 1 < v_.size(); ++k) inv_[k] = 1.0 / (v_[k + 1] - v_[k]);
    // Runs of consecutive pieces whose defining values are all exactly 0.
    // Piece p holds v in [v_{p−1}, v_p) (−∞ before the first knot, +∞ after
    // the last); pieces between duplicate knots are never selected but
    // still break a run (conservative).
    const std::size_t n = v_.size();
    if (n == 0) return;
    auto zero = [](const Value& y) {
        for (double c : y)
            if (c != 0.0) return false;
        return true;
    };
    auto zero_piece = [&](std::size_t p) {
        if (p == 0) return zero(y_.front());
        if (p >= n) return zero(y_.back());
        return zero(y_[p - 1]) && zero(y_[p]);
    };
    for (std::size_t p = 0; p <= n;) {
        if (!zero_piece(p)) {
            ++p;
            continue;
        }
        std::size_t q = p;
        while (q + 1 <= n && zero_piece(q + 1)) ++q;
        zero_runs_.push_back({p == 0 ? -INFINITY : v_[p - 1], q >= n ? INFINITY : v_[q]});
        p = q + 1;
    }
}

template <int N>
bool PiecewiseLinear<N>::zero_on(double a, double b) const {
    if (!(a <= b)) return false;  // also NaN
    // piece(a) and piece(b) in one run [start, end): start ≤ a and b < end
    for (const auto& [start, end] : zero_runs_)
        if (start <= a) {
            if (b < end) return true;
        } else {
            break;
        }
    return false;
}

template class PiecewiseLinear<1>;
template class PiecewiseLinear<3>;

double opacity_to_extinction(double a, double unit_distance) {
    return -std::log1p(-std::min(a, 1.0 - 1e-6)) / unit_distance;  // eq. (19)
}

Classifier::Classifier(const TransferFunction& tf, double default_unit_distance)
    : associated_(tf.associated) {
    std::vector<std::pair<double, std::array<double, 1>>> s;
    s.reserve(tf.alpha_points.size());
    const double u = tf.opacity_unit_distance.value_or(default_unit_distance);
    for (const auto& [v, a] : tf.alpha_points) {
        const double sigma =
            tf.alpha_kind == TransferFunction::Alpha::opacity ? opacity_to_extinction(a, u) : a;
        s.push_back({v, {sigma}});
    }
    sigma_ = PiecewiseLinear<1>(std::move(s));
    color_ = PiecewiseLinear<3>(tf.color_points);
    std::vector<std::pair<double, std::array<double, 1>>> g;
    for (const auto& [m, f] : tf.gradient_opacity_points) g.push_back({m, {f}});
    grad_opacity_ = PiecewiseLinear<1>(std::move(g));
    for (const auto& p : tf.alpha_points) breaks_.push_back(p.first);
    for (const auto& p : tf.color_points) breaks_.push_back(p.first);
    std::sort(breaks_.begin(), breaks_.end());
    breaks_.erase(std::unique(breaks_.begin(), breaks_.end()), breaks_.end());
    if (!sigma_.empty() && !color_.empty()) build_integrals();
}

void Classifier::build_integrals() {
    using F = IntegralFunctions;
    F& f = integrals_;
    f.knots = breaks_;
    const std::size_t m = breaks_.size();
    for (auto& c : f.col) c.assign(m + 1, 0.0);
    // Row p's σ and c: linear from (v0, σ0, c0) to (v1, σ1, c1), on the
    // pieces chosen at vm (one-sided limits at jumps).
    auto set_row = [&](std::size_t p, double v0, double v1, double vm, double inv_width) {
        const std::size_t ps = sigma_.piece(vm), pc = color_.piece(vm);
        const double s0 = sigma_.on_piece(ps, v0)[0], s1 = sigma_.on_piece(ps, v1)[0];
        const Rgb c0 = color_.on_piece(pc, v0), c1 = color_.on_piece(pc, v1);
        f.col[F::kStart][p] = v0;
        f.col[F::kInvWidth][p] = inv_width;
        f.col[F::kSigma][p] = s0;
        f.col[F::kHalfRise][p] = inv_width == 0.0 ? 0.0 : 0.5 * (s1 - s0);
        for (std::size_t k = 0; k < 3; ++k) {
            // g over the piece as A + B·w + C·w² (preintegrated.h's sources)
            const double dc = inv_width == 0.0 ? 0.0 : c1[k] - c0[k];
            const double ds = inv_width == 0.0 ? 0.0 : s1 - s0;
            const double a = associated_ ? c0[k] : s0 * c0[k];
            const double b = associated_ ? dc : s0 * dc + c0[k] * ds;
            const double c = associated_ ? 0.0 : ds * dc;
            f.col[F::kA + k][p] = a;
            f.col[F::kB + k][p] = 0.5 * b;
            f.col[F::kC + k][p] = c / 3.0;
        }
    };
    set_row(0, breaks_.front(), breaks_.front(), -INFINITY, 0.0);  // before the first breakpoint
    for (std::size_t p = 1; p < m; ++p) {
        const double v0 = breaks_[p - 1], v1 = breaks_[p];
        set_row(p, v0, v1, 0.5 * (v0 + v1), 1.0 / (v1 - v0));
        // the integrals at the next row's start: this row's at v1
        f.col[F::kS][p + 1] = f.S(p, v1);
        const Rgb g = f.G(p, v1);
        for (std::size_t k = 0; k < 3; ++k) f.col[F::kG + k][p + 1] = g[k];
    }
    set_row(m, breaks_.back(), breaks_.back(), INFINITY, 0.0);  // after the last
    for (auto& c : f.col) c.resize((m + 1 + 7) / 8 * 8, c[m]);
}

namespace {

using nlohmann::json;

double finite_number(const json& j, const std::string& subject, const std::string& where) {
    if (!j.is_number()) throw Error(subject, where + ": expected a number, got " + j.dump());
    const double x = j.get<double>();
    if (!std::isfinite(x)) throw Error(subject, where + ": number is not finite");
    return x;
}

// Reads [[v, x...], ...] with `width` numbers per point, sorted by v.
std::vector<std::vector<double>> read_points(const json& j, const std::string& key, std::size_t width,
                                             const std::string& subject) {
    if (!j.is_array()) throw Error(subject, "'" + key + "' must be a list of points");
    if (j.empty()) throw Error(subject, "'" + key + "' is an empty list");
    std::vector<std::vector<double>> pts;
    for (std::size_t i = 0; i < j.size(); ++i) {
        const std::string where = "'" + key + "' point " + std::to_string(i);
        const json& p = j[i];
        if (!p.is_array() || p.size() != width)
            throw Error(subject, where + ": expected " + std::to_string(width) + " numbers, got " + p.dump());
        std::vector<double> row;
        for (std::size_t c = 0; c < width; ++c) row.push_back(finite_number(p[c], subject, where));
        if (!pts.empty() && row[0] < pts.back()[0])
            throw Error(subject, where + ": points are not sorted by value (" + std::to_string(row[0]) +
                                     " after " + std::to_string(pts.back()[0]) + ")");
        pts.push_back(std::move(row));
    }
    return pts;
}

}  // namespace

TransferFunction tf_from_json(const nlohmann::json& j, const std::string& subject) {
    if (!j.is_object()) throw Error(subject, "a transfer function must be a JSON object");
    static const std::array<std::string, 8> kKeys{
        "format",          "name", "color", "emission", "opacity", "extinction", "opacity_unit_distance",
        "gradient_opacity"};
    for (const auto& [key, value] : j.items())
        if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end())
            throw Error(subject, "unknown key '" + key + "' in transfer function");
    if (!j.contains("format")) throw Error(subject, "missing 'format' (expected \"fathom-tf/1\")");
    if (j["format"] != "fathom-tf/1")
        throw Error(subject, "format " + j["format"].dump() + " is not \"fathom-tf/1\"");
    TransferFunction tf;
    if (j.contains("name")) {
        if (!j["name"].is_string()) throw Error(subject, "'name' must be a string");
        tf.name = j["name"].get<std::string>();
    }
    const bool has_color = j.contains("color"), has_emission = j.contains("emission");
    if (has_color == has_emission) throw Error(subject, "give exactly one of 'color' and 'emission'");
    const bool has_opacity = j.contains("opacity"), has_ext = j.contains("extinction");
    if (has_opacity == has_ext) throw Error(subject, "give exactly one of 'opacity' and 'extinction'");
    if (has_ext && j.contains("opacity_unit_distance"))
        throw Error(subject, "'opacity_unit_distance' is only allowed with 'opacity', not with 'extinction'");

    tf.associated = has_emission;
    const std::string ckey = has_color ? "color" : "emission";
    for (const auto& p : read_points(j[ckey], ckey, 4, subject)) {
        for (int c = 1; c < 4; ++c)
            if (p[c] < 0)
                throw Error(subject,
                            "'" + ckey + "' has a negative component at v = " + std::to_string(p[0]));
        tf.color_points.push_back({p[0], {p[1], p[2], p[3]}});
    }
    tf.alpha_kind = has_opacity ? TransferFunction::Alpha::opacity : TransferFunction::Alpha::extinction;
    const std::string akey = has_opacity ? "opacity" : "extinction";
    for (const auto& p : read_points(j[akey], akey, 2, subject)) {
        if (has_opacity && (p[1] < 0 || p[1] > 1))
            throw Error(subject, "'opacity' " + std::to_string(p[1]) + " at v = " + std::to_string(p[0]) +
                                     " is outside [0, 1]");
        if (!has_opacity && p[1] < 0)
            throw Error(subject, "'extinction' is negative at v = " + std::to_string(p[0]));
        tf.alpha_points.push_back({p[0], p[1]});
    }
    if (j.contains("opacity_unit_distance")) {
        const double u = finite_number(j["opacity_unit_distance"], subject, "'opacity_unit_distance'");
        if (u <= 0) throw Error(subject, "'opacity_unit_distance' must be > 0");
        tf.opacity_unit_distance = u;
    }
    if (j.contains("gradient_opacity"))
        for (const auto& p : read_points(j["gradient_opacity"], "gradient_opacity", 2, subject)) {
            if (p[0] < 0)
                throw Error(subject,
                            "'gradient_opacity' has a negative gradient magnitude " + std::to_string(p[0]));
            if (p[1] < 0 || p[1] > 1)
                throw Error(subject, "'gradient_opacity' factor " + std::to_string(p[1]) +
                                         " at |grad| = " + std::to_string(p[0]) + " is outside [0, 1]");
            tf.gradient_opacity_points.push_back({p[0], p[1]});
        }
    return tf;
}

nlohmann::json tf_to_json(const TransferFunction& tf) {
    json j;
    j["format"] = "fathom-tf/1";
    if (!tf.name.empty()) j["name"] = tf.name;
    json c = json::array();
    for (const auto& [v, rgb] : tf.color_points) c.push_back({v, rgb[0], rgb[1], rgb[2]});
    j[tf.associated ? "emission" : "color"] = c;
    json a = json::array();
    for (const auto& [v, x] : tf.alpha_points) a.push_back({v, x});
    j[tf.alpha_kind == TransferFunction::Alpha::opacity ? "opacity" : "extinction"] = a;
    if (tf.opacity_unit_distance) j["opacity_unit_distance"] = *tf.opacity_unit_distance;
    if (!tf.gradient_opacity_points.empty()) {
        json g = json::array();
        for (const auto& [m, f] : tf.gradient_opacity_points) g.push_back({m, f});
        j["gradient_opacity"] = g;
    }
    return j;
}

nlohmann::json parse_json_text(std::string_view text, const std::string& subject) {
    try {
        return json::parse(text.begin(), text.end());
    } catch (const json::exception& e) {
        throw Error(subject, std::string("invalid JSON: ") + e.what());
    }
}

std::string read_text_file(const std::filesystem::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) throw Error(path.string(), "cannot open file");
    if (std::filesystem::is_directory(path)) throw Error(path.string(), "is a directory, expected a file");
    std::ostringstream ss;
    ss << in.rdbuf();
    return ss.str();
}

TransferFunction TransferFunction::from_json_text(std::string_view text, const std::string& subject) {
    return tf_from_json(parse_json_text(text, subject), subject);
}

TransferFunction TransferFunction::from_file(const std::filesystem::path& path) {
    // fathom-tf/1, a 3D Slicer presets file or a ParaView colormap, found
    // from the content (src/tf/tf_interchange.cpp).
    return read_transfer_function(path);
}

std::string TransferFunction::to_json() const {
    return tf_to_json(*this).dump(2);
}

}  // namespace fathom
