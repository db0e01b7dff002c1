#include "fathom/volume.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <new>

#ifdef __linux__
#include <sys/mman.h>
#endif

#include "fathom/error.h"

namespace fathom {

namespace detail {

namespace {
constexpr std::size_t kHugePage = std::size_t{2} << 20;
}

void* allocate_samples(std::size_t bytes) {
    if (bytes < kHugePage) return ::operator new(bytes);
    void* p = ::operator new (bytes, std::align_val_t{kHugePage});
#ifdef MADV_HUGEPAGE
    // Advice only: where it is refused (no THP, "never"), the pages stay 4 KiB.
    madvise(p, bytes / kHugePage * kHugePage, MADV_HUGEPAGE);
#endif
    return p;
}

void free_samples(void* p, std::size_t bytes) noexcept {
    if (bytes < kHugePage)
        ::operator delete(p);
    else
        ::operator delete (p, std::align_val_t{kHugePage});
}

}  // namespace detail

std::size_t dtype_size(DType t) {
    return visit_dtype(t, []<class T>(T*) { return sizeof(T); });
}

std::string_view dtype_name(DType t) {
    switch (t) {
        case DType::u8:
            return "uint8";
        case DType::i8:
            return "int8";
        case DType::u16:
            return "uint16";
        case DType::i16:
            return "int16";
        case DType::u32:
            return "uint32";
        case DType::i32:
            return "int32";
        case DType::f32:
            return "float32";
        case DType::f64:
            break;
    }
    return "float64";
}

std::optional<DType> find_dtype(std::string_view name) {
    static constexpr std::array<std::pair<std::string_view, DType>, 10> kNames{{
        {"uint8", DType::u8},
        {"int8", DType::i8},
        {"uint16", DType::u16},
        {"int16", DType::i16},
        {"uint32", DType::u32},
        {"int32", DType::i32},
        {"float32", DType::f32},
        {"float64", DType::f64},
        {"float", DType::f32},
        {"double", DType::f64},
    }};
    for (const auto& [n, t] : kNames)
        if (n == name) return t;
    return std::nullopt;
}

DType parse_dtype(std::string_view name, const std::string& subject) {
    if (const auto t = find_dtype(name)) return *t;
    throw Error(subject, "unknown sample type '" + std::string(name) +
                             "' (expected uint8, int8, uint16, int16, uint32, int32, float32 or float64)");
}

Volume::Volume(std::array<std::int64_t, 3> dims, DType type, int components)
    : dims_(dims), dtype_(type), components_(components) {
    if (components < 1) throw Error("volume", "component count must be at least 1");
    std::uint64_t bytes = dtype_size(type) * static_cast<std::uint64_t>(components);
    for (auto d : dims) {
        if (d < 1) throw Error("volume", "every dimension must be at least 1");
        if (bytes > kMaxVolumeBytes / static_cast<std::uint64_t>(d))
            throw Error("volume", "grid of " + std::to_string(dims[0]) + "x" + std::to_string(dims[1]) + "x" +
                                      std::to_string(dims[2]) + " is larger than the " +
                                      std::to_string(kMaxVolumeBytes >> 30) + " GiB limit");
        bytes *= static_cast<std::uint64_t>(d);
    }
    bytes_.resize(bytes);
}

double Volume::value_linear(std::int64_t n) const {
    return visit_dtype(dtype_, [&]<class T>(T*) { return static_cast<double>(data<T>()[n]); });
}

double Volume::value(std::int64_t i, std::int64_t j, std::int64_t k, int c) const {
    return value_linear(c + components_ * (i + dims_[0] * (j + dims_[1] * k)));
}

void Volume::set_value(std::int64_t i, std::int64_t j, std::int64_t k, double v, int c) {
    const std::int64_t n = c + components_ * (i + dims_[0] * (j + dims_[1] * k));
    visit_dtype(dtype_, [&]<class T>(T*) { data<T>()[n] = static_cast<T>(v); });
}

void Volume::set_axes(const Mat3& m, const std::string& subject) {
    for (const auto& row : m.m)
        for (double x : row)
            if (!std::isfinite(x)) throw Error(subject, "axis directions contain a non-finite number");
    if (m.determinant() == 0.0) throw Error(subject, "axis directions are singular (zero volume)");
    axes_ = m;
}

Vec3 Volume::spacing() const {
    return {length(axes_.column(0)), length(axes_.column(1)), length(axes_.column(2))};
}

double Volume::smallest_spacing() const {
    const Vec3 s = spacing();
    return std::min({s.x, s.y, s.z});
}

Vec3 Volume::world_to_index(const Vec3& p) const {
    return axes_.inverse() * (p - origin_);
}

std::array<double, 2> Volume::value_range() const {
    return visit_dtype(dtype_, [&]<class T>(T*) {
        const T* p = data<T>();
        const std::size_t n = bytes_.size() / sizeof(T);
        double lo = std::numeric_limits<double>::infinity();
        double hi = -lo;
        if constexpr (std::is_floating_point_v<T>) {
            for (std::size_t i = 0; i < n; ++i) {
                const double v = p[i];
                if (!std::isfinite(v)) continue;
                lo = std::min(lo, v);
                hi = std::max(hi, v);
            }
        } else {
            if (n > 0) {  // a reduction by value, which vectorizes (minmax_element does not)
                T mn = p[0], mx = p[0];
                for (std::size_t i = 1; i < n; ++i) {
                    mn = std::min(mn, p[i]);
                    mx = std::max(mx, p[i]);
                }
                lo = mn;
                hi = mx;
            }
        }
        if (lo > hi) lo = hi = 0.0;
        return std::array<double, 2>{lo, hi};
    });
}

}  // namespace fathom
