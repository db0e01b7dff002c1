#include "volume/bricks.h"

#include <algorithm>
#include <cstdint>
#include <cstring>
#include <utility>

#ifdef __linux__
#include <sys/mman.h>
#endif

#include "fathom/error.h"

#include "core/parallel.h"

namespace fathom {

namespace {

constexpr std::uintptr_t kHugePage = std::uintptr_t{2} << 20;

/// Hands the whole pages of [from, to) back to the system (their contents
/// read as zeros afterwards); returns the end of the last page handed back
/// (`from` where none was). Whole 2 MiB pages: the samples sit in huge
/// pages where the system has them, and handing back part of one would
/// split it.
std::byte* release_pages(std::byte* from, std::byte* to) {
    const auto a = (reinterpret_cast<std::uintptr_t>(from) + kHugePage - 1) / kHugePage * kHugePage;
    const auto b = reinterpret_cast<std::uintptr_t>(to) / kHugePage * kHugePage;
    if (b <= a) return from;
#ifdef MADV_DONTNEED
    madvise(reinterpret_cast<void*>(a), b - a, MADV_DONTNEED);
#endif
    return from + (b - reinterpret_cast<std::uintptr_t>(from));
}

}  // namespace

std::uint64_t Bricks::bytes_for(const Volume& v) {
    return static_cast<std::uint64_t>(nodes_for(v.dims())) * dtype_size(v.dtype());
}

Bricks::Bricks(Volume& v, bool release, int threads) {
    const auto& d = v.dims();
    if (v.components() != 1 || d[0] < 2 || d[1] < 2 || d[2] < 2)
        throw Error("bricks", "need a 1-component volume with at least 2 samples along each axis");
    for (int a = 0; a < 3; ++a) nb_[a] = bricks_along(d[a]);
    last_planes_ = last_planes_along(d[2]);
    const std::size_t sz = dtype_size(v.dtype());
    size_ = static_cast<std::size_t>(bytes_for(v));
    // Not zero-filled: every byte is written below, and pages are touched
    // only as their slab is.
    data_ = static_cast<std::byte*>(detail::allocate_samples(size_));
    std::byte* src = v.bytes();
    const auto row = static_cast<std::size_t>(d[0]) * sz, plane = row * static_cast<std::size_t>(d[1]);
    const std::int64_t per_slab = nb_[0] * nb_[1];
    std::byte* released = src;  // the pages before it are handed back
    for (std::int64_t bz = 0; bz < nb_[2]; ++bz) {
        parallel_chunks(per_slab, threads, [&](std::int64_t b0, std::int64_t b1) {
            for (std::int64_t b = b0; b < b1; ++b) {
                const std::int64_t bx = b % nb_[0], by = b / nb_[0];
                const std::int64_t planes = bz == nb_[2] - 1 ? last_planes_ : kNodes;
                std::byte* out =
                    data_ +
                    static_cast<std::size_t>(bz * per_slab * kBrickNodes + b * kNodes * kNodes * planes) * sz;
                const std::int64_t x0 = bx * kCells, run = std::min(kNodes, d[0] - x0);
                for (std::int64_t z = 0; z < planes; ++z) {
                    const std::int64_t gz =
                        bz * kCells + z;  // the last slab ends at the lattice's last plane
                    for (std::int64_t y = 0; y < kNodes; ++y, out += kNodes * sz) {
                        const std::int64_t gy = std::min(by * kCells + y, d[1] - 1);
                        const std::byte* in = src + static_cast<std::size_t>(gz) * plane +
                                              static_cast<std::size_t>(gy) * row +
                                              static_cast<std::size_t>(x0) * sz;
                        std::memcpy(out, in, static_cast<std::size_t>(run) * sz);
                        // past the lattice (no cell reads these; written so
                        // that no byte a gather fetches is undefined)
                        for (std::int64_t x = run; x < kNodes; ++x)
                            std::memcpy(out + x * sz, in + (run - 1) * sz, sz);
                    }
                }
            }
        });
        if (release) {  // the next slab starts at plane kCells·(bz + 1)
            const std::size_t done =
                std::min(v.size_bytes(), static_cast<std::size_t>(kCells * (bz + 1)) * plane);
            released = release_pages(released, src + done);
        }
    }
}

Bricks::~Bricks() {
    if (data_ != nullptr) detail::free_samples(data_, size_);
}

Bricks::Bricks(Bricks&& o) noexcept
    : data_(std::exchange(o.data_, nullptr)),
      size_(std::exchange(o.size_, 0)),
      nb_{o.nb_[0], o.nb_[1], o.nb_[2]},
      last_planes_(o.last_planes_) {}

Bricks& Bricks::operator=(Bricks&& o) noexcept {
    if (this != &o) {
        if (data_ != nullptr) detail::free_samples(data_, size_);
        data_ = std::exchange(o.data_, nullptr);
        size_ = std::exchange(o.size_, 0);
        std::copy(o.nb_, o.nb_ + 3, nb_);
        last_planes_ = o.last_planes_;
    }
    return *this;
}

}  // namespace fathom
