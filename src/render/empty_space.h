// Exact empty-space skipping (docs/performance.md "Empty-space skipping").
//
// The lattice's cells are grouped into macrocells of c³ cells (c = 2^shift). A
// macrocell holds the range [min, max] of its nodes (its boundary nodes
// included), which bounds every trilinear sample inside it. It is *empty*
// when the medium is exactly zero over that range under the frame's model:
// σ = 0 (absorption), g = 0 (emission), both (emission–absorption); for
// pre-classified grids, when every density node is exactly 0.
//
// A sample inside an empty macrocell gives a segment with transmittance
// exactly 1 and radiance exactly 0, which leaves both accumulators unchanged
// bit for bit; so does a pre-integrated segment whose two ends lie in one
// box of empty macrocells (the trilinear field is continuous along the
// segment, which stays in the box, so every value of the ramp between the
// ends is taken in the box, where the medium is zero; and where every
// empty macrocell's range lies in one interval of zero medium,
// joins_empty(), it is enough that both ends lie in empty macrocells: the
// ramp between them stays in that interval). The integrators
// therefore skip such runs of samples without changing the image, and keep
// the uniform segment division of eq. (8): a run ends on the segment grid,
// at the last sample whose *computed* position still falls into the box.
// Sample positions p0 + dp·t with t = t_near + x·δ are monotone in x per
// axis (IEEE rounding is monotone), so the samples between two samples of
// one box are in it too; the run's end is estimated from the ray's exit
// from the box and then verified on the computed position.
#pragma once

#include <algorithm>
#include <array>
#include <atomic>
#include <cmath>
#include <cstddef>
#include <cstdint>
#include <limits>
#include <memory>
#include <mutex>
#include <vector>

#include "fathom/camera.h"
#include "fathom/math.h"
#include "fathom/render.h"
#include "fathom/transfer_function.h"
#include "fathom/volume.h"

#include "integrate/ray_span.h"

// Small functions on the per-sample path that GCC otherwise leaves out of line.
#define FATHOM_INLINE inline __attribute__((always_inline))

namespace fathom {

/// The medium under model m is exactly zero for every scalar in [a, b]:
/// σ = 0 (absorption), g = 0 (emission: g = σ·c is zero with σ or c, q for
/// an associated emission), both (emission–absorption). Conservative.
inline bool medium_zero_on(const Classifier& tf, Model m, double a, double b) {
    const bool no_sigma = tf.sigma_zero_on(a, b);
    if (m == Model::absorption) return no_sigma;
    if (tf.associated()) return (m == Model::emission || no_sigma) && tf.color_zero_on(a, b);
    return no_sigma || (m == Model::emission && tf.color_zero_on(a, b));
}

/// The largest E such that the medium under model m is exactly zero for
/// every scalar below E (−∞: none; +∞: everywhere): E is a control value.
inline double zero_below(const Classifier& tf, Model m) {
    if (m != Model::emission_absorption && m != Model::absorption && m != Model::emission) return -INFINITY;
    if (medium_zero_on(tf, m, -INFINITY, std::numeric_limits<double>::max())) return INFINITY;
    double e = -INFINITY;
    for (double k : tf.breakpoints())
        if (k > e && medium_zero_on(tf, m, -INFINITY, std::nextafter(k, -INFINITY))) e = k;
    return e;
}

/// Where the camera rays of one frame can meet non-empty macrocells
/// (EmptySpace::pixel_bounds): for pixel (x, y), every point of the ray
/// through its centre (Camera::generate) that lies within `kMargin` index
/// units of a non-empty macrocell has its parameter t in [lo, hi]; lo > hi
/// where the ray meets none.
struct PixelBounds {
    int width = 0;
    std::vector<float> lo, hi;  // per pixel, row-major; empty: no bounds (lo = −∞, hi = +∞)
    /// The other threads' bounds before they merge (scratch, kept with the
    /// bounds so that the next frame's reuse its pages).
    std::vector<std::vector<float>> spare_lo, spare_hi;
    /// How far (index units, per axis) around each macrocell the bounds
    /// hold: far more than rounding moves a computed sample position.
    static constexpr double kMargin = 1.0 / 64.0;
    [[nodiscard]] bool any() const { return !lo.empty(); }
    /// No bounds (the storage kept).
    void clear() {
        width = 0;
        lo.clear();
        hi.clear();
    }
    /// The bounds of pixel (x, y).
    void at(int x, int y, double& t_lo, double& t_hi) const {
        if (lo.empty()) {
            t_lo = -INFINITY;
            t_hi = INFINITY;
            return;
        }
        const std::size_t k =
            static_cast<std::size_t>(y) * static_cast<std::size_t>(width) + static_cast<std::size_t>(x);
        t_lo = lo[k];
        t_hi = hi[k];
    }
};

/// The macrocells of a lattice: c³ cells each (c = 2^shift), the last ones
/// per axis clipped; the cell of a position is the one GridSampler picks.
class MacrocellLattice {
public:
    MacrocellLattice() = default;
    MacrocellLattice(const Volume& v, int shift) : MacrocellLattice(v.dims(), shift) {}
    MacrocellLattice(const std::array<std::int64_t, 3>& nodes, int shift);
    /// Macrocells per axis of a lattice of `nodes` with 2^shift cells per edge.
    [[nodiscard]] static std::array<std::int64_t, 3> dims_of(const std::array<std::int64_t, 3>& nodes,
                                                             int shift);
    /// Macrocells per axis.
    [[nodiscard]] const std::array<std::int64_t, 3>& dims() const { return dims_; }
    /// Cells per macrocell edge (2^shift).
    [[nodiscard]] int edge() const { return 1 << shift_; }
    /// log2 of edge().
    [[nodiscard]] int shift() const { return shift_; }
    /// Lattice nodes per axis.
    [[nodiscard]] const std::array<std::int64_t, 3>& nodes() const { return nodes_; }
    /// The longest step along an index axis (cells) after which the
    /// computed position of the next sample still lies in a macrocell
    /// touching the last one: a macrocell edge less a cell (a step of a
    /// whole edge, rounded, can pass a macrocell).
    [[nodiscard]] double touching_step() const {
        return static_cast<double>((std::int64_t{1} << shift_) - 1);
    }
    /// The macrocell of a position, the cell chosen as GridSampler picks it.
    [[nodiscard]] FATHOM_INLINE std::array<std::int64_t, 3> macrocell(const Vec3& p) const {
        return {axis_cell(p.x, 0) >> shift_, axis_cell(p.y, 1) >> shift_, axis_cell(p.z, 2) >> shift_};
    }
    /// Macrocell m's place in x-fastest order.
    [[nodiscard]] FATHOM_INLINE std::size_t index(const std::array<std::int64_t, 3>& m) const {
        return static_cast<std::size_t>(m[0] + dims_[0] * (m[1] + dims_[1] * m[2]));
    }

protected:
    [[nodiscard]] FATHOM_INLINE std::int64_t axis_cell(double p, int a) const {
        const double x = std::clamp(p, 0.0, node_hi_[a]);
        return std::min(static_cast<std::int64_t>(x), nodes_[a] - 2);
    }

    int shift_ = 3;
    std::array<std::int64_t, 3> nodes_{};
    std::array<double, 3> node_hi_{};     // nodes_ − 1
    std::array<std::int64_t, 3> dims_{};  // macrocells per axis
};

namespace detail {
/// Anonymous pages: those never written take no memory, and freed ones go
/// back to the system at once (not to the allocator's free lists).
struct Unmap {
    std::size_t bytes = 0;
    void operator()(std::uint8_t* p) const noexcept;
};
using Pages = std::unique_ptr<std::uint8_t[], Unmap>;
Pages map_pages(std::size_t bytes);
/// Faults in the pages of p[0 … bytes) at once, before they are written
/// (where the kernel can: Linux 5.14 and later): a fault per page costs
/// several times as much on some virtual machines.
void populate(std::uint8_t* p, std::size_t bytes);
/// A table's build shared by the threads that need the table at once
/// (empty_space.cpp).
struct SharedBuild;
}  // namespace detail

class EmptySpace : public MacrocellLattice {
    struct Octants;

public:
    EmptySpace() = default;
    /// A scalar volume classified by `tf` under model `m`, macrocells of
    /// 2^shift cells per edge.
    static EmptySpace for_scalar(const Volume& v, const Classifier& tf, Model m, int shift, int threads);
    /// Empty where every node is exactly 0, so is every sample: a
    /// pre-classified grid's density, or the scalar of the average
    /// projection, to which zeros add nothing.
    static EmptySpace for_zeros(const Volume& v, int shift, int threads);
    /// Empty where every node is exactly `value` (finite), so is every
    /// sample (a lerp between equal values is that value): MIP's lowest
    /// value, which no sample's maximum needs.
    static EmptySpace for_value(const Volume& v, double value, int shift, int threads);
    /// Isosurfaces: "empty" where every sample lies on the same side of
    /// each iso-value (x < iso or not; the node range widened as
    /// MacrocellRanges widens it). Two such macrocells that touch share a
    /// node, so they lie on the same sides: a ray's samples that step to a
    /// touching macrocell each time (at most a macrocell edge per axis)
    /// cross no iso-value while they stay in such macrocells.
    static EmptySpace for_isosurfaces(const Volume& v, const std::vector<double>& isos, int shift,
                                      int threads);

    /// The macrocells of `shift` with none of them empty: what ray packets
    /// walk where nothing is skipped (each ray's span one run).
    /// joins_empty() holds (there is no empty macrocell to join).
    static EmptySpace none(const Volume& v, int shift);

    /// Macrocells of twice the edge, empty where the (up to) 8 of these
    /// inside them are: where joins_empty(), the classification for_scalar
    /// gives them (every empty range lies below E, and so does their union;
    /// a macrocell of twice the edge holds exactly the nodes of its 8), at a
    /// pass over this grid instead of the volume. Only where joins_empty().
    [[nodiscard]] EmptySpace coarser() const;

    /// True when at least one macrocell is empty (else skipping is pointless).
    [[nodiscard]] bool any() const { return any_; }
    /// True when every empty macrocell's range lies in one interval of
    /// scalars where the medium is zero (below zero_below's E; for
    /// pre-classified grids, density 0): then a linear ramp between two
    /// samples in empty macrocells, in one box or not, stays in that
    /// interval, and a pre-integrated segment between them is empty too.
    [[nodiscard]] bool joins_empty() const { return joins_empty_; }
    [[nodiscard]] double empty_fraction() const;
    /// The share of the blocks of 2×2×2 cells inside non-empty macrocells
    /// (the shift must be at least 1) whose bit in `blocks` is clear:
    /// simd::active_cells's bits of this lattice. 0 without non-empty ones.
    [[nodiscard]] double inactive_share(const std::vector<std::uint32_t>& blocks) const;
    /// The share of empty macrocells in the groups of 2×2×2 of them (from
    /// macrocell 0, clipped to the grid) that hold a non-empty one: about
    /// what macrocells of twice the edge would evaluate and these skip. 0
    /// without non-empty ones.
    [[nodiscard]] double empty_share_in_pairs() const;

    /// The frame's PixelBounds for `camera` and a width × height image of a
    /// lattice placed by `axes` (index → world) and `origin`: the box of
    /// every non-empty macrocell that borders an empty one or the grid's
    /// edge, widened by PixelBounds::kMargin, is projected onto the image
    /// (a ray can enter and leave the non-empty macrocells only through
    /// such a box). No bounds (PixelBounds::any() false) unless the whole
    /// lattice lies in front of the camera and the camera's axes are
    /// orthonormal.
    /// `threads`: at most, one per `boxes_per_thread` boxes (each thread
    /// draws its share into bounds of its own, then they merge: the same
    /// bounds for any count).
    [[nodiscard]] PixelBounds pixel_bounds(const Camera& camera, int width, int height, const Mat3& axes,
                                           const Vec3& origin, int threads,
                                           std::size_t boxes_per_thread = 16384) const {
        PixelBounds out;
        pixel_bounds(out, camera, width, height, axes, origin, threads, boxes_per_thread);
        return out;
    }
    /// The same into `out`, reusing its storage (a renderer's frame after frame).
    void pixel_bounds(PixelBounds& out, const Camera& camera, int width, int height, const Mat3& axes,
                      const Vec3& origin, int threads, std::size_t boxes_per_thread = 16384) const;

    /// The cap of distance_ahead.
    static constexpr int kMaxDistance = 255;

    [[nodiscard]] FATHOM_INLINE bool empty(const std::array<std::int64_t, 3>& m) const {
        return empty_[index(m)] != 0;
    }
    /// Per macrocell in index order: 1 where empty.
    [[nodiscard]] const std::uint8_t* empty_bytes() const { return empty_.data(); }
    /// The largest D such that the box from m reaching D − 1 macrocells
    /// ahead in octant `o` (bit a set: axis a goes down), clipped to the
    /// grid, holds only macrocells of m's kind (empty or not; capped at
    /// kMaxDistance): a ray leaving m in that octant crosses the whole
    /// region of m's kind ahead of it in one step.
    [[nodiscard]] int distance_ahead(const std::array<std::int64_t, 3>& m, int o) const {
        return ahead(o)[index(m)];
    }
    /// distance_ahead of every macrocell in octant o (index order), built
    /// on first use: a frame needs the octants its rays travel in only.
    /// Valid while the Use it is read under lasts.
    [[nodiscard]] const std::uint8_t* ahead(int o) const;
    /// Per axis a and macrocell m in octant o, at a·N + index(m) (N the
    /// macrocell count): how far (macrocells, capped at kMaxDistance) the
    /// box ahead of m reaches along axis a when it keeps its distance_ahead
    /// D across: the boxes ahead of the macrocells D, then D + D′ further
    /// along a, where they are of m's kind and reach at least D, joined to
    /// m's (at most two of them). Every macrocell of that longer box is of
    /// m's kind. Each axis (bit a of `axes`) is built on first use: only
    /// those asked for so far are valid (simd::PacketWalk).
    [[nodiscard]] const std::uint8_t* along(int o, unsigned axes) const;

    /// A stretch of work that reads the octants' tables (ahead(), along()):
    /// they stay valid while it lasts. A Use that `releases` (a frame of
    /// Renderer::render) first frees, where no other Use is in flight, the
    /// tables that nothing has read since the previous releasing Use began,
    /// so that a moving camera keeps the tables of about two frames'
    /// octants, not of all eight (rebuilt where a later frame needs them
    /// again; the images do not change).
    class Use {
    public:
        Use(const EmptySpace& es, bool releases);
        ~Use();
        Use(const Use&) = delete;
        Use& operator=(const Use&) = delete;

    private:
        std::shared_ptr<Octants> oc_;
    };
    /// Bytes the octants' tables hold now (built axes and octants only).
    [[nodiscard]] std::size_t table_bytes() const;

    /// A box of macrocells.
    struct Box {
        std::array<std::int64_t, 3> lo, hi;  // macrocell indices, inclusive
        [[nodiscard]] FATHOM_INLINE bool contains(const std::array<std::int64_t, 3>& c) const {
            return c[0] >= lo[0] && c[0] <= hi[0] && c[1] >= lo[1] && c[1] <= hi[1] && c[2] >= lo[2] &&
                   c[2] <= hi[2];
        }
    };
    /// The box reaching r macrocells ahead of m in octant o, clipped to the grid.
    [[nodiscard]] FATHOM_INLINE Box box_ahead(const std::array<std::int64_t, 3>& m, std::int64_t r,
                                              int o) const {
        Box b;
        for (int a = 0; a < 3; ++a) {
            const bool down = ((o >> a) & 1) != 0;
            b.lo[a] = down ? std::max<std::int64_t>(m[a] - r, 0) : m[a];
            b.hi[a] = down ? m[a] : std::min<std::int64_t>(m[a] + r, dims_[a] - 1);
        }
        return b;
    }

    /// The node coordinate of box b's face on axis a: the far one (up) or
    /// the near one, clipped to the lattice.
    [[nodiscard]] FATHOM_INLINE double box_face(const Box& b, int a, bool up) const {
        return static_cast<double>(up ? std::min((b.hi[a] + 1) << shift_, nodes_[a] - 1) : b.lo[a] << shift_);
    }

private:
    friend class RunFinder;  // reads ahead() by index()
    /// Macrocells whose node range [lo, hi] satisfies empty(lo, hi) are empty.
    template <class Empty>
    static EmptySpace from_ranges(const Volume& v, int shift, int threads, Empty&& empty);
    /// ahead()'s plane of macrocells zi (counted from the octant's far
    /// side) into `out`, row by row once `job`'s plane zi − 1 has done the
    /// rows ahead of each; `best` holds a row's bytes (scratch).
    void build_ahead(int o, std::uint8_t* out, std::int64_t zi, detail::SharedBuild& job,
                     std::uint8_t* best) const;
    /// along()'s axis a (its N bytes at `row`) on the macrocells of plane z
    /// (that plane's pages faulted in first, as build_ahead's).
    void build_along(int o, int a, std::uint8_t* row, std::int64_t z) const;
    /// Per macrocell of `groups` (twice the edge): 1 where the (up to) 8 of
    /// these inside it are all empty.
    [[nodiscard]] std::vector<std::uint8_t> groups_empty(const MacrocellLattice& groups) const;
    void find_border();

    std::vector<std::uint8_t> empty_;  // per macrocell: 1 where empty
    struct Octants {                   // distance_ahead and along() per octant, built on demand
        struct Table {
            std::mutex build;
            std::atomic<const std::uint8_t*> ahead{nullptr};
            std::atomic<unsigned> along_axes{0};  // bit a: along()'s axis a built
            std::atomic<bool> read{false};        // since the last releasing Use began
            detail::Pages ahead_pages, along_pages;
            // the builds in flight, which threads that need the table join
            std::shared_ptr<detail::SharedBuild> ahead_job, along_job;
        };
        std::array<Table, 8> table;
        std::mutex uses_mutex;
        int uses = 0;  // Uses in flight
    };
    std::shared_ptr<Octants> ahead_ = std::make_shared<Octants>();  // shared by copies
    std::vector<std::uint32_t> border_;  // non-empty macrocells next to an empty one or the grid's edge
    bool any_ = false;
    bool joins_empty_ = false;
};

/// The node range of every macrocell, widened by a margin for rounding, for
/// skipping where a ray's result depends on the scalar's range alone (mip,
/// minip, isosurfaces): every trilinear sample GridSampler computes in a
/// macrocell lies in its [lo, hi] (a NaN node makes it [−∞, +∞]). The
/// range [a, b] of the nodes is widened by 2^−40·max(|a|, |b|) on each side
/// where rounding may leave it: a trilinear value is a convex combination
/// of its cell's corners, and its three levels of rounding move it by a few
/// ulps of that at most. Not where they cannot: a = 0, or b an integer
/// with every node ≥ 0 (mirrored: b = 0, or a an integer with every node
/// ≤ 0), so that a ray whose largest sample is such a bound still skips.
class MacrocellRanges : public MacrocellLattice {
public:
    MacrocellRanges() = default;
    MacrocellRanges(const Volume& v, int shift, int threads);

    /// True when every macrocell in the box from a's macrocell to b's has
    /// its range in [lo, hi]: then so has every sample at a position
    /// between a and b on each axis (a ray's samples between two of its
    /// samples, whose computed positions are monotone per axis).
    [[nodiscard]] bool within(const Vec3& a, const Vec3& b, double lo, double hi) const {
        return box(a, b, [&](const float* r) { return r[0] >= lo && r[1] <= hi; });
    }
    /// The smallest lo and largest hi over the box from macrocell ma to mb
    /// (MacrocellLattice::macrocell of two positions a and b): every sample
    /// at a position between a and b lies in between.
    [[nodiscard]] std::array<double, 2> bounds(const std::array<std::int64_t, 3>& ma,
                                               const std::array<std::int64_t, 3>& mb) const {
        float lo = INFINITY, hi = -INFINITY;  // (the floats' extremes are their doubles')
        box(ma, mb, [&](const float* r) {
            lo = std::min(lo, r[0]);
            hi = std::max(hi, r[1]);
            return true;
        });
        return {static_cast<double>(lo), static_cast<double>(hi)};
    }
    /// The ranges of macrocells 2^levels times as large along each axis
    /// (the lattice's shift + levels): each the smallest lo and largest hi
    /// of the macrocells it holds, whose indices are its own shifted up by
    /// `levels` (so a box of them holds the box of these between the same
    /// positions).
    [[nodiscard]] MacrocellRanges coarser(int levels) const;
    /// The smallest lo and the largest hi over all macrocells: no sample
    /// lies outside.
    [[nodiscard]] double lowest() const { return lowest_; }
    [[nodiscard]] double highest() const { return highest_; }
    /// The smallest finite node value (+∞: none), not widened.
    [[nodiscard]] double lowest_node() const { return lowest_node_; }
    /// The widened range of the macrocell holding p (tests).
    [[nodiscard]] std::array<double, 2> range(const Vec3& p) const {
        const std::size_t i = 2 * index(macrocell(p));
        return {range_[i], range_[i + 1]};
    }

private:
    /// f(range) for each macrocell of the box from a's macrocell to b's
    /// until it returns false; true when none did.
    template <class F>
    FATHOM_INLINE bool box(const Vec3& a, const Vec3& b, F&& f) const {
        return box(macrocell(a), macrocell(b), f);
    }
    template <class F>
    FATHOM_INLINE bool box(const std::array<std::int64_t, 3>& ma, const std::array<std::int64_t, 3>& mb,
                           F&& f) const {
        std::array<std::int64_t, 3> m0{}, m1{};
        for (int k = 0; k < 3; ++k) {
            m0[k] = std::min(ma[k], mb[k]);
            m1[k] = std::max(ma[k], mb[k]);
        }
        for (std::int64_t z = m0[2]; z <= m1[2]; ++z)
            for (std::int64_t y = m0[1]; y <= m1[1]; ++y) {
                const float* r = range_.data() + 2 * index({m0[0], y, z});
                for (std::int64_t x = m0[0]; x <= m1[0]; ++x, r += 2)
                    if (!f(r)) return false;
            }
        return true;
    }

    std::vector<float> range_;  // lo, hi per macrocell, as floats rounded outwards
    double lowest_ = INFINITY, highest_ = -INFINITY, lowest_node_ = INFINITY;
};

/// The packets' walk (simd::trace_packets) may end an empty run
/// kExitMargin samples short of the computed exit x of its box
/// (floor(x − kExitMargin), RunFinder::estimated_last's x) without
/// last_in's check of the last sample's macrocell, for a ray that crosses
/// every axis it crosses (A ≠ 0) at a step of at least kSureStep nodes and
/// whose numbers are bounded as below, in a lattice of at most 10⁵ nodes a
/// side. Then x = f·A + B is off the exact crossing by a few 10⁻⁷ samples
/// at most (|f·A| ≤ 10⁸, |B| ≤ 10⁷, B's own terms ≤ 10⁸), and a sample's
/// computed position off its exact one by below 10⁻¹⁰ nodes (|p0|, |dp·t|
/// ≤ 2·10⁵), 10⁻⁷ samples at that step: far below the margin, so the sample
/// at the floor lies inside the box. The run ends at most one sample early;
/// the samples it leaves are sampled or walked next, every sample skipped
/// still lies in an empty macrocell, and the images keep their bits.
/// (RunFinder keeps its check: without it the one-by-one walk measured
/// 0.98×.)
inline constexpr double kExitMargin = 1e-5, kSureStep = 1e-3;
inline bool exits_are_sure(const double* dp, double delta, const double* A, const double* B, const double* p0,
                           const double* nodes) {
    for (int a = 0; a < 3; ++a) {
        if (!(nodes[a] <= 1e5)) return false;
        if (A[a] == 0.0) continue;  // never crossed: never bounds a run
        if (!(std::abs(dp[a]) * delta >= kSureStep && std::abs(B[a]) <= 1e7 && std::abs(p0[a]) <= 1e5))
            return false;
    }
    return true;
}

/// Sample positions on the segment grid: index j sits at
/// t_near + (j − first + offset)·δ (first = 1 and the in-segment offset for
/// the point samples of segments 1..n; first = 0, offset = 0 for the
/// segment ends 0..n of pre-integration). The integrators sample through
/// this, so the run finder sees the very positions they sample.
struct SampleGrid {
    const RaySpan* span;
    double delta, offset;
    std::int64_t first;
    [[nodiscard]] FATHOM_INLINE double t(std::int64_t j) const {
        return span->t_near + (static_cast<double>(j - first) + offset) * delta;
    }
    [[nodiscard]] FATHOM_INLINE Vec3 at(std::int64_t j) const { return span->at(t(j)); }
    /// The samples before the ray's first point near a non-empty
    /// macrocell, or after its last (RaySpan::occupied_lo/hi, which must
    /// not be crossed: lo ≤ hi), lie in empty ones: j ≤ [0] or j ≥ [1]
    /// (∓kFar where a bound is infinite), one sample of slack each way
    /// covering the rounding of t.
    static constexpr std::int64_t kFar = std::int64_t{1} << 60;
    [[nodiscard]] std::array<std::int64_t, 2> outside_occupied() const {
        const RaySpan& sp = *span;
        const auto index_at = [&](double t) {  // the fractional sample index at t, clamped
            const double x = (t - sp.t_near) / delta - offset + static_cast<double>(first);
            return std::clamp(x, -0x1p52, 0x1p52);  // ±∞ too
        };
        std::array<std::int64_t, 2> out{-kFar, kFar};
        if (sp.occupied_lo > -INFINITY)
            out[0] = static_cast<std::int64_t>(std::floor(index_at(sp.occupied_lo))) - 1;
        if (sp.occupied_hi < INFINITY)
            out[1] = static_cast<std::int64_t>(std::ceil(index_at(sp.occupied_hi))) + 1;
        return out;
    }
};

/// Walks runs of samples through macrocells for one ray: run(j, dir, limit)
/// finds the macrocell of sample j and the farthest sample index k (from j
/// towards `limit` in direction dir = ±1) still in it, so that samples j..k
/// all lie in that macrocell.
class RunFinder {
public:
    struct Run {
        std::int64_t last;  // k
        bool empty;         // the macrocell is empty
    };

    RunFinder(const EmptySpace& es, SampleGrid grid) : es_(es), g_(grid) {
        for (int a = 0; a < 3; ++a)  // the octant a ray travels in: forward, and backward
            if (grid.span->dp[a] < 0.0) octant_fwd_ |= 1 << a;
        octant_back_ = 7 ^ octant_fwd_;
        // The fractional sample index where the ray crosses node coordinate
        // f on axis a, f·A + B (the inverse of SampleGrid::at along a);
        // axes the ray does not cross (or hardly) never bound a run.
        const RaySpan& sp = *grid.span;
        for (int a = 0; a < 3; ++a) {
            const double A = 1.0 / (sp.dp[a] * grid.delta);
            const bool crosses = std::isfinite(A);
            for (int d = 0; d < 2; ++d) {  // d = 0: forward, 1: backward
                Axis& ax = axes_[d][a];
                ax.up = (sp.dp[a] > 0.0) == (d == 0);
                ax.A = crosses ? A : 0.0;
                ax.B = crosses ? (-sp.p0[a] / sp.dp[a] - sp.t_near) / grid.delta - grid.offset +
                                     static_cast<double>(grid.first)
                               : (d == 0 ? INFINITY : -INFINITY);
            }
        }
        // Samples outside the ray's pixel bounds lie in empty macrocells.
        if (!(sp.occupied_lo <= sp.occupied_hi)) {  // the ray meets none
            before_ = kNever;
            return;
        }
        const auto outside = grid.outside_occupied();
        before_ = outside[0];
        after_ = outside[1];
    }

    /// A run crosses the box ahead of sample j's macrocell, in the ray's
    /// octant, that holds only macrocells of its kind (distance_ahead). An
    /// empty run holds only samples in empty macrocells (verified on the
    /// computed positions). A non-empty run goes to the estimated exit from
    /// its box, unverified: a sample evaluated in an empty macrocell gives
    /// (1, 0) anyway, so only the skipped runs need to be exact. With
    /// `exact`, non-empty runs are verified too: every sample of a run then
    /// lies in its box (the differentiable renderer computes no gradient in
    /// empty macrocells).
    Run run(std::int64_t j, int dir, std::int64_t limit, bool exact = false) const {
        if (j <= before_) return {dir > 0 ? std::min(before_, limit) : limit, true};
        if (j >= after_) return {dir > 0 ? limit : std::max(after_, limit), true};
        const auto m = macrocell_of(j);
        const int o = dir > 0 ? octant_fwd_ : octant_back_;
        // the box ahead of the ray that holds only macrocells of m's kind
        const EmptySpace::Box b = es_.box_ahead(m, ahead(dir)[es_.index(m)] - 1, o);
        if (es_.empty(m) || exact) return {last_in(b, j, dir, limit), es_.empty(m)};
        const std::int64_t k = estimated_last(b, j, dir, limit);
        if (k != limit) remember(k + dir);  // where the next run starts, long before it is asked
        return {k, false};
    }

    /// The octant of the forward walk (bit a: the ray goes down axis a),
    /// its axes (the fractional sample index at node coordinate f on axis
    /// a is f·A[a] + B[a]) and the samples j ≤ before, j ≥ after that lie
    /// in empty macrocells: what run(j, +1, limit) computes from, for a
    /// walk that repeats it elsewhere (simd::trace_packets).
    void forward_walk(int& octant, double* A, double* B, double& before, double& after) const {
        octant = octant_fwd_;
        for (int a = 0; a < 3; ++a) {
            A[a] = axes_[0][a].A;
            B[a] = axes_[0][a].B;
        }
        before = static_cast<double>(before_);
        after = static_cast<double>(after_);
    }

    /// As run(), but an empty run goes on through the boxes of empty
    /// macrocells that follow it: each of its samples lies in an empty
    /// macrocell, though not all in one box.
    Run run_through(std::int64_t j, int dir, std::int64_t limit) const {
        const Run r = run(j, dir, limit);
        if (!r.empty) return r;
        const int o = dir > 0 ? octant_fwd_ : octant_back_;
        std::int64_t k = r.last;
        while (k != limit) {
            const auto m = macrocell_of(k + dir);
            if (!es_.empty(m)) break;
            k = last_in(es_.box_ahead(m, ahead(dir)[es_.index(m)] - 1, o), k + dir, dir, limit);
        }
        return {k, true};
    }

private:
    // The estimated farthest index from j towards limit whose position is in
    // box b (sample j is in it), within [j, limit]: where the ray leaves the
    // box (an estimate: callers verify on computed positions where it
    // matters).
    [[nodiscard]] FATHOM_INLINE std::int64_t estimated_last(const EmptySpace::Box& b, std::int64_t j, int dir,
                                                            std::int64_t limit) const {
        const auto& ax = axes_[dir > 0 ? 0 : 1];
        double x = dir > 0 ? INFINITY : -INFINITY;
        for (int a = 0; a < 3; ++a) {
            const double xa = es_.box_face(b, a, ax[a].up) * ax[a].A + ax[a].B;
            x = dir > 0 ? std::min(x, xa) : std::max(x, xa);
        }
        if (!std::isfinite(x)) return limit;
        const double lo = static_cast<double>(std::min(j, limit)),
                     hi = static_cast<double>(std::max(j, limit));
        x = std::clamp(x, lo, hi);  // ≥ 0: truncation is floor
        const auto k = static_cast<std::int64_t>(x);
        return dir > 0 ? k : k + static_cast<std::int64_t>(static_cast<double>(k) < x);  // floor, ceil
    }
    // The farthest index from j towards limit whose position is in box b
    // (sample j is in it).
    [[nodiscard]] FATHOM_INLINE std::int64_t last_in(const EmptySpace::Box& b, std::int64_t j, int dir,
                                                     std::int64_t limit) const {
        std::int64_t k = estimated_last(b, j, dir, limit);
        // Verify on the computed positions (rounding can move the last one out).
        for (;;) {
            const auto mk = es_.macrocell(g_.at(k));
            if (k != limit) remember(k + dir);  // alongside the check: they do not wait on each other
            if (k == j || b.contains(mk)) return k;
            k -= dir;
        }
    }
    // distance_ahead in the octant of direction dir (fetched once).
    [[nodiscard]] FATHOM_INLINE const std::uint8_t* ahead(int dir) const {
        const std::uint8_t*& a = dir > 0 ? ahead_fwd_ : ahead_back_;
        if (a == nullptr) a = es_.ahead(dir > 0 ? octant_fwd_ : octant_back_);
        return a;
    }
    // The macrocell of sample j's computed position (remembered or not).
    [[nodiscard]] FATHOM_INLINE std::array<std::int64_t, 3> macrocell_of(std::int64_t j) const {
        if (j == next_j_) {
            // Read word by word, as remember() stored it: a 16-byte load of
            // words stored one by one waits for the stores to retire
            // instead of taking their values from the store buffer (3 %
            // of a bone frame; docs/performance.md, "Empty-space skipping").
            const volatile std::int64_t* m = next_m_.data();
            return {m[0], m[1], m[2]};
        }
        return es_.macrocell(g_.at(j));
    }
    FATHOM_INLINE void remember(std::int64_t j) const {
        next_j_ = j;
        next_m_ = es_.macrocell(g_.at(j));
    }

    struct Axis {
        double A, B;  // the fractional index at node coordinate f: f·A + B
        bool up;      // the run leaves through the box's far face on this axis
    };
    const EmptySpace& es_;
    SampleGrid g_;
    std::array<std::array<Axis, 3>, 2> axes_{};  // forward, backward
    int octant_fwd_ = 0, octant_back_ = 7;
    static constexpr std::int64_t kNever = SampleGrid::kFar;
    // Samples j ≤ before_ or ≥ after_ lie in empty macrocells.
    std::int64_t before_ = -kNever, after_ = kNever;
    // The macrocell of sample next_j_, where the next run likely starts.
    mutable const std::uint8_t* ahead_fwd_ = nullptr;
    mutable const std::uint8_t* ahead_back_ = nullptr;
    mutable std::int64_t next_j_ = kNever;
    mutable std::array<std::int64_t, 3> next_m_{};
};

}  // namespace fathom
