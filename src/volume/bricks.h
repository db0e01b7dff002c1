// Bricked storage of a scalar volume for the SIMD sampler
// (docs/performance.md "Bricks"). The lattice's cells are grouped into
// bricks of kCells³; each brick stores its kNodes³ = (kCells + 1)³ nodes
// x-fastest, the nodes of its far faces repeated from the next brick (or
// the lattice's last node where the brick passes the lattice's end), so
// that the eight corners of any cell lie in one brick and a corner and its
// +x neighbour stay adjacent. Bricks follow one another x-fastest too, and
// those of the last slab along z store only the planes of nodes the
// lattice has (kNodes² · last_planes() nodes each; z is the slowest axis,
// so only that slab's places change).
//
// A ray crossing the volume along z then stays within 33·33 nodes of a
// plane for 32 steps, where the x-fastest layout moves nx·ny samples per
// step; along x the rows are 33 nodes long instead of nx.
#pragma once

#include <array>
#include <cstddef>
#include <cstdint>

#include "fathom/volume.h"

namespace fathom {

class Bricks {
public:
    static constexpr std::int64_t kCells = 32;
    static constexpr std::int64_t kNodes = kCells + 1;
    static constexpr std::int64_t kBrickNodes = kNodes * kNodes * kNodes;

    Bricks() = default;
    /// The bricks of a 1-component volume (every dimension ≥ 2). With
    /// `release`, v's sample pages are handed back to the system slab by
    /// slab as they are copied, so that the two copies never coexist in
    /// memory: v's samples read as zeros afterwards (its caller discards it).
    Bricks(Volume& v, bool release, int threads);
    ~Bricks();
    Bricks(Bricks&& o) noexcept;
    Bricks& operator=(Bricks&& o) noexcept;
    Bricks(const Bricks&) = delete;
    Bricks& operator=(const Bricks&) = delete;

    [[nodiscard]] bool empty() const { return data_ == nullptr; }
    [[nodiscard]] const std::byte* bytes() const { return data_; }
    [[nodiscard]] std::size_t size_bytes() const { return size_; }
    /// Bricks along x, y and z.
    [[nodiscard]] std::int64_t bricks_x() const { return nb_[0]; }
    [[nodiscard]] std::int64_t bricks_y() const { return nb_[1]; }
    [[nodiscard]] std::int64_t bricks_z() const { return nb_[2]; }
    /// The planes of nodes each brick of the last slab along z stores (2 …
    /// kNodes).
    [[nodiscard]] std::int64_t last_planes() const { return last_planes_; }
    /// The storage index of the first corner of cell (i, j, k) (0 ≤ i ≤
    /// nx − 2, ...); its other corners follow at +1 (x), +kNodes (y) and
    /// +kNodes² (z).
    [[nodiscard]] std::int64_t cell_index(std::int64_t i, std::int64_t j, std::int64_t k) const {
        const std::int64_t bz = k / kCells;
        const std::int64_t per = bz == nb_[2] - 1 ? kNodes * kNodes * last_planes_ : kBrickNodes;
        return bz * nb_[0] * nb_[1] * kBrickNodes + (i / kCells + nb_[0] * (j / kCells)) * per + i % kCells +
               kNodes * (j % kCells + kNodes * (k % kCells));
    }
    /// Bricks along an axis of n ≥ 2 nodes: ⌈(n − 1)/kCells⌉.
    static std::int64_t bricks_along(std::int64_t n) { return (n - 2) / kCells + 1; }
    /// The planes of nodes the last of the bricks along an axis of n nodes needs.
    static std::int64_t last_planes_along(std::int64_t n) { return n - (bricks_along(n) - 1) * kCells; }
    /// The nodes a brick of the last slab stores, for a lattice of nz nodes along z.
    static std::int64_t last_brick_nodes(std::int64_t nz) { return kNodes * kNodes * last_planes_along(nz); }
    /// The nodes the bricks of a lattice of d nodes store.
    static std::int64_t nodes_for(const std::array<std::int64_t, 3>& d) {
        const std::int64_t per_slab = bricks_along(d[0]) * bricks_along(d[1]);
        return per_slab * ((bricks_along(d[2]) - 1) * kBrickNodes + last_brick_nodes(d[2]));
    }
    /// The storage size of a volume's bricks, in bytes.
    static std::uint64_t bytes_for(const Volume& v);

private:
    std::byte* data_ = nullptr;
    std::size_t size_ = 0;
    std::int64_t nb_[3] = {0, 0, 0};
    std::int64_t last_planes_ = kNodes;
};

}  // namespace fathom
