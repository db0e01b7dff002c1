// Volume: a typed, node-centred scalar (or multi-component) grid with its
// placement in world space (SPEC §2).
//
// Memory layout: x fastest, then y, then z, then nothing: the components of
// one node are adjacent (index = c + C·(i + nx·(j + ny·k))). Samples keep
// the type they were stored in (uint8 stays uint8); bytes are held in the
// machine's native byte order.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fathom/math.h"

namespace fathom {

enum class DType : std::uint8_t { u8, i8, u16, i16, u32, i32, f32, f64 };

/// Size of one sample of the type, in bytes.
std::size_t dtype_size(DType t);
/// Canonical name: "uint8", "int8", "uint16", "int16", "uint32", "int32", "float32", "float64".
std::string_view dtype_name(DType t);
/// A canonical name (also "float" and "double") → its type; nullopt when unknown.
std::optional<DType> find_dtype(std::string_view name);
/// Parses a canonical name (also "float" and "double"); throws Error(subject, ...) when unknown.
DType parse_dtype(std::string_view name, const std::string& subject);

/// Upper bound on the number of samples any reader accepts (2^34 bytes of
/// data at most): a header claiming more is an error, not an allocation.
inline constexpr std::uint64_t kMaxVolumeBytes = std::uint64_t{1} << 34;

namespace detail {
/// Storage for a volume's samples. Blocks of 2 MiB or more are aligned to
/// 2 MiB and, where the system has them, marked for transparent huge pages:
/// rays gather from all over the grid (a step along z moves nx·ny samples),
/// and one TLB entry then covers 2 MiB instead of 4 KiB.
void* allocate_samples(std::size_t bytes);
void free_samples(void* p, std::size_t bytes) noexcept;

template <class T>
struct SampleAllocator {
    using value_type = T;
    SampleAllocator() = default;
    template <class U>
    SampleAllocator(const SampleAllocator<U>&) noexcept {}
    T* allocate(std::size_t n) { return static_cast<T*>(allocate_samples(n * sizeof(T))); }
    void deallocate(T* p, std::size_t n) noexcept { free_samples(p, n * sizeof(T)); }
    friend bool operator==(const SampleAllocator&, const SampleAllocator&) { return true; }
};
}  // namespace detail

class Volume {
public:
    Volume() = default;
    /// A zero-filled grid. Throws Error when a dimension is < 1, components
    /// is < 1, or the size exceeds kMaxVolumeBytes.
    Volume(std::array<std::int64_t, 3> dims, DType type, int components = 1);

    [[nodiscard]] const std::array<std::int64_t, 3>& dims() const { return dims_; }
    [[nodiscard]] DType dtype() const { return dtype_; }
    [[nodiscard]] int components() const { return components_; }
    [[nodiscard]] std::int64_t num_nodes() const { return dims_[0] * dims_[1] * dims_[2]; }
    [[nodiscard]] std::size_t size_bytes() const { return bytes_.size(); }

    [[nodiscard]] std::byte* bytes() { return bytes_.data(); }
    [[nodiscard]] const std::byte* bytes() const { return bytes_.data(); }
    template <class T>
    [[nodiscard]] T* data() {
        return reinterpret_cast<T*>(bytes_.data());
    }
    template <class T>
    [[nodiscard]] const T* data() const {
        return reinterpret_cast<const T*>(bytes_.data());
    }

    /// Sample (i, j, k), component c, converted to double (no bounds check).
    [[nodiscard]] double value(std::int64_t i, std::int64_t j, std::int64_t k, int c = 0) const;
    /// Linear sample index n (node index · components + c), as double.
    [[nodiscard]] double value_linear(std::int64_t n) const;
    /// Sets sample (i, j, k), component c, converting from double.
    void set_value(std::int64_t i, std::int64_t j, std::int64_t k, double v, int c = 0);

    // --- placement (SPEC §2): node (i,j,k) sits at origin + M·(i,j,k) ---
    [[nodiscard]] const Vec3& origin() const { return origin_; }
    /// Columns of M are the world steps along i, j and k.
    [[nodiscard]] const Mat3& axes() const { return axes_; }
    void set_origin(const Vec3& o) { origin_ = o; }
    /// Sets M = diag(spacing).
    void set_spacing(const Vec3& s) { axes_ = Mat3::diagonal(s); }
    /// Sets a general M; throws Error(subject) when it is singular or not finite.
    void set_axes(const Mat3& m, const std::string& subject = {});
    /// Length of each column of M.
    [[nodiscard]] Vec3 spacing() const;
    /// The shortest column of M ("smallest spacing", SPEC §2).
    [[nodiscard]] double smallest_spacing() const;
    /// World position of node (i, j, k) (fractional indices allowed).
    [[nodiscard]] Vec3 index_to_world(const Vec3& ijk) const { return origin_ + axes_ * ijk; }
    [[nodiscard]] Vec3 world_to_index(const Vec3& p) const;

    /// Smallest and largest finite sample over all components.
    [[nodiscard]] std::array<double, 2> value_range() const;

private:
    std::array<std::int64_t, 3> dims_{0, 0, 0};
    DType dtype_ = DType::u8;
    int components_ = 1;
    std::vector<std::byte, detail::SampleAllocator<std::byte>> bytes_;
    Vec3 origin_{0, 0, 0};
    Mat3 axes_ = Mat3::identity();
};

/// Calls f(static_cast<T*>(nullptr)) with T the C++ type of dtype t: the one
/// place where fathom branches on the sample type (once per frame or file).
template <class F>
decltype(auto) visit_dtype(DType t, F&& f) {
    switch (t) {
        case DType::u8:
            return f(static_cast<std::uint8_t*>(nullptr));
        case DType::i8:
            return f(static_cast<std::int8_t*>(nullptr));
        case DType::u16:
            return f(static_cast<std::uint16_t*>(nullptr));
        case DType::i16:
            return f(static_cast<std::int16_t*>(nullptr));
        case DType::u32:
            return f(static_cast<std::uint32_t*>(nullptr));
        case DType::i32:
            return f(static_cast<std::int32_t*>(nullptr));
        case DType::f32:
            return f(static_cast<float*>(nullptr));
        case DType::f64:
            break;
    }
    return f(static_cast<double*>(nullptr));
}

}  // namespace fathom
