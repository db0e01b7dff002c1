#include "fathom/info.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <string>
#include <type_traits>

namespace fathom {
namespace {

constexpr int kBins = 16;
constexpr int kBarWidth = 36;

std::string num(double v) {
    std::array<char, 32> buf{};
    std::snprintf(buf.data(), buf.size(), "%.6g", v == 0.0 ? 0.0 : v);  // no "-0"
    return buf.data();
}

std::string vec(const Vec3& v) {
    std::string r = "(";
    r.append(num(v.x)).append(", ").append(num(v.y)).append(", ").append(num(v.z)).push_back(')');
    return r;
}

std::string padded(const std::string& s, std::size_t width) {
    return s.size() >= width ? s : std::string(width - s.size(), ' ') + s;
}

std::string memory_size(std::size_t bytes) {
    static constexpr std::array<const char*, 4> kUnits{"KiB", "MiB", "GiB", "TiB"};
    if (bytes < 1024) return std::to_string(bytes) + " bytes";
    double v = static_cast<double>(bytes);
    std::size_t u = 0;
    for (v /= 1024.0; v >= 1024.0 && u + 1 < kUnits.size(); v /= 1024.0) ++u;
    std::array<char, 32> buf{};
    std::snprintf(buf.data(), buf.size(), "%.1f %s", v, kUnits[u]);
    return std::string(buf.data()) + " (" + std::to_string(bytes) + " bytes)";
}

/// World bounding box of the grid's nodes (the 8 corners under M).
std::pair<Vec3, Vec3> world_box(const Volume& v) {
    const auto& d = v.dims();
    Vec3 lo = v.origin(), hi = v.origin();
    for (int c = 0; c < 8; ++c) {
        const Vec3 ijk{(c & 1) ? static_cast<double>(d[0] - 1) : 0.0,
                       (c & 2) ? static_cast<double>(d[1] - 1) : 0.0,
                       (c & 4) ? static_cast<double>(d[2] - 1) : 0.0};
        const Vec3 p = v.index_to_world(ijk);
        for (int a = 0; a < 3; ++a) {
            lo[a] = std::min(lo[a], p[a]);
            hi[a] = std::max(hi[a], p[a]);
        }
    }
    return {lo, hi};
}

std::array<std::uint64_t, kBins> histogram(const Volume& v, double lo, double hi) {
    std::array<std::uint64_t, kBins> bins{};
    const double scale = hi > lo ? kBins / (hi - lo) : 0.0;
    visit_dtype(v.dtype(), [&]<class T>(T*) {
        const T* p = v.data<T>();
        const std::size_t n = v.size_bytes() / sizeof(T);
        for (std::size_t i = 0; i < n; ++i) {
            const double x = static_cast<double>(p[i]);
            if constexpr (std::is_floating_point_v<T>)
                if (!std::isfinite(x)) continue;
            const double t = (x - lo) * scale;  // NaN-safe: compare before converting
            const int b = t >= kBins ? kBins - 1 : (t > 0 ? static_cast<int>(t) : 0);
            ++bins[static_cast<std::size_t>(b)];
        }
    });
    return bins;
}

std::string histogram_text(const Volume& v, double lo, double hi) {
    if (v.size_bytes() == 0) return "";
    if (!(hi > lo)) return "histogram   every sample is " + num(lo) + "\n";
    const auto bins = histogram(v, lo, hi);
    const std::uint64_t most = *std::max_element(bins.begin(), bins.end());
    std::uint64_t least = most;
    for (auto c : bins)
        if (c > 0) least = std::min(least, c);
    const bool log_scale = most > 100 * least;
    std::string out = "histogram   16 bins" + std::string(v.components() > 1 ? ", all components" : "") +
                      (log_scale ? "; bar length ~ log(1 + count)" : "; bar length ~ count") + "\n";
    const double width = (hi - lo) / kBins;
    for (int b = 0; b < kBins; ++b) {
        const double c = static_cast<double>(bins[static_cast<std::size_t>(b)]);
        const double frac =
            log_scale ? std::log1p(c) / std::log1p(static_cast<double>(most)) : c / static_cast<double>(most);
        const int len = c > 0 ? std::max(1, static_cast<int>(std::lround(frac * kBarWidth))) : 0;
        const double b_hi = b + 1 == kBins ? hi : lo + (b + 1) * width;
        out += "  [" + padded(num(lo + b * width), 10) + ", " + padded(num(b_hi), 10) +
               (b + 1 == kBins ? "] " : ") ") + std::string(static_cast<std::size_t>(len), '#') +
               std::string(static_cast<std::size_t>(kBarWidth - len), ' ') +
               padded(std::to_string(bins[static_cast<std::size_t>(b)]), 12) + "\n";
    }
    return out;
}

}  // namespace

std::string describe_volume(const Volume& v, const std::string& name) {
    const auto& d = v.dims();
    std::string out = "file        " + name + "\n";
    out += "dims        " + std::to_string(d[0]) + " x " + std::to_string(d[1]) + " x " +
           std::to_string(d[2]) + "  (" + std::to_string(v.num_nodes()) + " nodes)\n";
    out += "components  " + std::to_string(v.components()) + "\n";
    out += "type        " + std::string(dtype_name(v.dtype())) + "\n";
    const Vec3 s = v.spacing();
    out += "spacing     " + num(s.x) + " x " + num(s.y) + " x " + num(s.z) + "\n";
    out += "origin      " + vec(v.origin()) + "\n";
    if (!v.axes().is_diagonal()) {
        const char* label = "directions  ";
        for (int a = 0; a < 3; ++a, label = "            ")
            out += std::string(label) + "ijk"[a] + " " + vec(normalize(v.axes().column(a))) + "\n";
    }
    const auto [box_lo, box_hi] = world_box(v);
    out += "extent      " + vec(box_lo) + " .. " + vec(box_hi) + "\n";
    const auto range = v.value_range();
    out += "values      " + num(range[0]) + " .. " + num(range[1]) + "\n";
    out += "memory      " + memory_size(v.size_bytes()) + "\n";
    return out + histogram_text(v, range[0], range[1]);
}

}  // namespace fathom
