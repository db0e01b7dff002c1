// SIMD classification of point samples along one ray (docs/performance.md
// "SIMD"): positions, trilinear interpolation and the transfer function's
// σ(v) and c(v) for a batch of consecutive samples, several lanes at once,
// with runtime dispatch over the instruction sets this CPU has (Google
// Highway: SSE4, AVX2, AVX-512, or its scalar fallback).
//
// Every lane performs exactly the scalar code's operations in the same
// order (no fused multiply–add; the file is compiled with
// -ffp-contract=off), so the results are bit-identical to GridSampler and
// Classifier; tests check every target against the scalar path.
#pragma once

#include <algorithm>
#include <bit>
#include <cmath>
#include <cstdint>
#include <limits>
#include <string>
#include <type_traits>
#include <vector>

#include "fathom/math.h"
#include "fathom/render.h"
#include "fathom/transfer_function.h"
#include "fathom/volume.h"

namespace fathom {
struct ShadeSetup;  // render/shading.h
}

namespace fathom::simd {

/// Samples per batch (a multiple of every target's lane count).
inline constexpr int kBatch = 16;

/// Sample types whose corner pairs (q[0], q[1]) come from one gather: 32
/// bits for 8- and 16-bit integers, 64 for float32.
template <class T>
constexpr bool kPairs =
    std::is_same_v<T, std::uint8_t> || std::is_same_v<T, std::int8_t> || std::is_same_v<T, std::uint16_t> ||
    std::is_same_v<T, std::int16_t> || std::is_same_v<T, float>;

/// The most bytes of samples, x-fastest or in bricks, whose 8- and 16-bit
/// pairs are gathered (their byte offsets stay in int32 lanes).
inline constexpr std::int64_t kPairBytesMax = std::int64_t{1} << 30;

/// A piecewise-linear function flattened for lane-parallel evaluation.
struct FlatFunction {
    std::vector<double> knots;
    std::vector<double> y[3];  // per component; only y[0] for σ
    std::vector<double> inv;   // PiecewiseLinear::inverse_widths
    int components = 1;
    /// With at most kTable knots: the knots (row 0), each component's values
    /// (rows 1 …) and the inverse widths (row kInvRow), padded with the last,
    /// for lane permutations.
    static constexpr std::size_t kTable = 8;
    static constexpr std::size_t kInvRow = 4;
    alignas(64) double table[5][kTable] = {};
};

/// A transfer function's control values (Classifier::breakpoints) padded
/// to FlatFunction::kTable with the last, for lane permutations
/// (BatchSource::break_table), where they fit.
struct BreakTable {
    alignas(64) double values[FlatFunction::kTable] = {};
    bool fits = false;
    BreakTable() = default;
    explicit BreakTable(const std::vector<double>& breaks)
        : fits(!breaks.empty() && breaks.size() <= FlatFunction::kTable) {
        if (!fits) return;
        for (std::size_t i = 0; i < FlatFunction::kTable; ++i)
            values[i] = breaks[std::min(i, breaks.size() - 1)];
    }
    /// The table, or nullptr where the values do not fit.
    [[nodiscard]] const double* get() const { return fits ? values : nullptr; }
};

/// A point-sampled quadrature's segment rule (integrate/point_rules.h) that
/// classify_batch also applies, lane by lane, after the model.
enum class PointRule : std::uint8_t { none, riemann, alpha };

/// What the SIMD classifier needs: the volume, the ray's sample grid and
/// the transfer function.
struct BatchSource {
    const void* data = nullptr;
    DType type = DType::u8;
    std::int64_t nx = 0, ny = 0, nz = 0;
    const FlatFunction* sigma = nullptr;
    const FlatFunction* color = nullptr;
    /// Scalars below this give a medium that is exactly zero under the
    /// frame's model (render/empty_space.h zero_below): a vector of such
    /// samples is stored as σ = 0, c = 0 without evaluating the functions.
    double zero_below = -INFINITY;
    /// Optional (nullptr: none): the bits of active_cells for zero_below.
    /// A vector of samples in blocks without a set bit is below it:
    /// classify_batch stores it as zero without interpolating.
    const std::uint32_t* active = nullptr;
    /// For pre-integration (simd_preint.h): the transfer function's control
    /// values (Classifier::breakpoints) and whether color is an emission q.
    const std::vector<double>* breaks = nullptr;
    /// Optional (nullptr: none): `breaks` padded to FlatFunction::kTable
    /// with the last, 64-byte aligned, where they fit (break_table()): the
    /// ramp's cuts pick their control value by lane permutation.
    const double* break_table = nullptr;
    bool associated = false;
    /// Optional (nullptr: the ramp's pieces): the transfer function's
    /// integral functions (Classifier::integrals), for the segments without
    /// self-attenuation.
    const IntegralFunctions* integrals = nullptr;
    /// With a rule: classify_batch also turns each sample into its segment
    /// (BatchOut::t, radiance) under `model` with δ = RayGrid::delta, as the
    /// scalar rule does (the same bits). Shaded media need `shade` too.
    PointRule rule = PointRule::none;
    /// Optional (nullptr: unshaded): with a rule, each sample that is not
    /// zero is shaded before the model (ShadedScalarMedium::shade: gradient
    /// by central differences, Blinn–Phong under RayGrid::view, gradient
    /// opacity; the same bits). On-the-fly gradients only.
    const ShadeSetup* shade = nullptr;
    Model model = Model::emission_absorption;
    /// Bricks along x, y and z where `data` holds the samples in bricks
    /// (volume/bricks.h; the paired sample types only, at most 1 GiB); 0:
    /// `data` is x-fastest.
    std::int64_t bricks_x = 0, bricks_y = 0, bricks_z = 0;
    /// σ and c on the same knots (same_knots(*sigma, *color)): one piece
    /// lookup per value serves both. Set once with the functions, not per batch.
    bool shared_knots = false;
};

/// Blocks of 2 × 2 × 2 cells (3³ nodes, clipped to the lattice), bx = nx/2
/// by ny/2 by nz/2 of them: bit i + bx·(j + by·k) is set where some node of
/// block (i, j, k) is not below e (NaN included). A trilinear value is a
/// convex combination of its cell's corners, and rounding keeps it within
/// them, so a sample in a block without a set bit lies below e. One bit per
/// 8 cells: 1/64 of the volume's size in 8-bit samples. Empty when v's
/// sample type has no paired gathers or v has 2³¹ nodes or more.
std::vector<std::uint32_t> active_cells(const Volume& v, double e, int threads);

struct RayGrid {
    Vec3 p0, dp;
    double t_near = 0, delta = 0, offset = 0;
    std::int64_t first = 1;
    /// With BatchSource::shade: the unit vector toward the eye
    /// (ShadedScalarMedium::view).
    Vec3 view{};
};

/// The samples a batch holds, b0..b1: up to `size` (kBatch unless said)
/// from the one asked for, in the direction of travel, not beyond `run_end`
/// (the end of the run being evaluated: what follows may be skipped).
struct Window {
    std::int64_t b0 = std::numeric_limits<std::int64_t>::min() / 2, b1 = b0;
    [[nodiscard]] bool holds(std::int64_t j) const { return j >= b0 && j <= b1; }
    [[nodiscard]] int count() const { return static_cast<int>(b1 - b0 + 1); }
    void start_at(std::int64_t j, bool forward, std::int64_t run_end, std::int64_t size = kBatch) {
        if (forward) {
            b0 = j;
            b1 = std::min<std::int64_t>(j + size - 1, std::max(j, run_end));
        } else {
            b0 = std::max<std::int64_t>(j - size + 1, std::min(j, run_end));
            b1 = j;
        }
    }
};

/// σ and c (or q) of samples j0 .. j0 + kBatch − 1.
struct BatchOut {
    alignas(64) double sigma[kBatch];
    alignas(64) double color[3][kBatch];
    /// Bit l set: sample j0 + l is below BatchSource::zero_below, so the
    /// medium is exactly zero there under the frame's model.
    std::uint32_t zero = 0;
    /// With BatchSource::rule: each sample's segment, transmittance t_i and
    /// radiance C_i (1 and 0 where `zero`).
    alignas(64) double t[kBatch];
    alignas(64) double radiance[3][kBatch];
};

/// The fewest samples (or pre-integrated segments) an evaluated run of a
/// skipping walk covers. A batch costs about as much for the 9 samples of
/// a typical run in a bone shell as for 16, and finding the next run costs
/// about as much as a batch (a chain of dependent lookups), so a short run
/// goes on over what follows it: samples in empty macrocells give (1, 0)
/// anyway, and those below the zero range are skipped by their bits
/// (docs/performance.md, "Empty-space skipping").
inline constexpr std::int64_t kLeastRun = 2 * kBatch;

/// The last index of an evaluated run from i in direction dir (±1) that
/// ends at `last`, taken on to at least kLeastRun indices but not past
/// `bound`.
inline std::int64_t least_run_end(std::int64_t i, int dir, std::int64_t last, std::int64_t bound) {
    return dir > 0 ? std::min(bound, std::max(last, i + kLeastRun - 1))
                   : std::max(bound, std::min(last, i - kLeastRun + 1));
}

/// The samples from lane l of a batch, in direction dir (±1), at most
/// `avail` of them: k > 0 when the first k are zero (bit set in `zero`),
/// −k when the first k are not (the skip convention of composite()).
/// (`zero`: 32 or 64 bits.)
template <class Bits>
std::int64_t split_zero(Bits zero, std::int64_t l, int dir, std::int64_t avail) {
    static_assert(std::is_same_v<Bits, std::uint32_t> || std::is_same_v<Bits, std::uint64_t>);
    constexpr std::int64_t kTop = std::numeric_limits<Bits>::digits - 1;
    const auto run = [&](Bits bits) {  // leading set bits from l in direction dir
        return dir > 0 ? std::countr_one(static_cast<Bits>(bits >> l))
                       : std::countl_one(static_cast<Bits>(bits << (kTop - l)));
    };
    const std::int64_t z = std::min<std::int64_t>(run(zero), avail);
    return z > 0 ? z : -std::min<std::int64_t>(run(~zero), avail);
}

/// Whether a and b have the same knots (and so the same inverse widths).
inline bool same_knots(const FlatFunction& a, const FlatFunction& b) {
    return a.knots == b.knots && a.inv == b.inv;
}

FlatFunction flatten(const PiecewiseLinear<1>& f);
FlatFunction flatten(const PiecewiseLinear<3>& f);

/// Classifies samples j0 .. j0 + count − 1 (count ≤ kBatch; whole vectors
/// are computed, so a few more may be filled) with the best target.
void classify_batch(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, BatchOut& out);

/// The trilinear scalar alone of samples j0 .. j0 + count − 1 (GridSampler's
/// bits), for pre-integration's segment ends, kBatch at a time (count <
/// 64); `out` holds count rounded up to a multiple of kBatch values (whole
/// vectors are computed) and is 64-byte aligned. With `below`, also bit l
/// for each sample below src.zero_below (l < count).
void interpolate_batch(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, double* out,
                       std::uint64_t* below = nullptr);

/// Ray packets (docs/performance.md "Ray packets"): the point-sampled
/// quadratures (BatchSource::rule, shaded with BatchSource::shade or not,
/// front to back, with skipping)
/// traced several rays at a time, one ray per lane, each lane walking its
/// own ray's macrocells and evaluating its own samples, with the same
/// operations on each lane as classify_batch and RunFinder on that ray, so
/// the same bits as the ray-by-ray path.
///
/// One ray: its sample grid (segments 1..n at t_near + (j − 1 + offset)·δ)
/// and RunFinder's forward walk.
struct PacketRay {
    double p0[3], dp[3];
    double t_near, delta, offset;
    double n;              // segments 1..n (an exact integer)
    double A[3], B[3];     // RunFinder's forward axes: the fractional index at node coordinate f is f·A + B
    double before, after;  // samples j ≤ before or ≥ after lie in empty macrocells
};

/// The axis of dp's largest |component| (the lower axis on ties): the axis
/// along which a packet lane takes EmptySpace::along's longer boxes.
inline int packet_main_axis(const double (&dp)[3]) {
    const double x = std::abs(dp[0]), y = std::abs(dp[1]), z = std::abs(dp[2]);
    return x >= y && x >= z ? 0 : y >= z ? 1 : 2;
}

/// The macrocells a packet walks (EmptySpace), in the octant all its rays
/// travel in.
struct PacketWalk {
    const std::uint8_t* empty = nullptr;  // per macrocell: 1 where empty
    const std::uint8_t* ahead = nullptr;  // distance_ahead in `octant`
    /// EmptySpace::along in `octant`: per axis, how far the box ahead
    /// reaches along it (3 × cells bytes; built for the rays' main axes).
    const std::uint8_t* along = nullptr;
    std::int64_t cells = 0;       // macrocells (at least 4)
    double dims[3] = {0, 0, 0};   // macrocells per axis
    double nodes[3] = {0, 0, 0};  // lattice nodes per axis
    int shift = 0;                // cells per macrocell edge: 2^shift
    int octant = 0;               // bit a: the rays go down axis a
};

struct PacketResult {
    double radiance[3];
    double alpha;
    double depth, first_hit;  // with trace_packets' `depth` (else not set)
};

/// The frame's lattice for prepare_packet_rays: index = M·(world − origin),
/// nodes 0 … nodes − 1 per axis, the step h (world units), and the point
/// samples' place in their segment (`offset`, RenderSettings::sample_point).
struct PacketFrame {
    double world_to_index[3][3];
    double origin[3];
    double node_hi[3];  // nodes − 1 per axis
    double h = 0, offset = 0;
};

/// Camera rays of a tile (world origin and direction, per ray) with their
/// PixelBounds [lo, hi] (lo ≤ hi), structure of arrays of `count` entries.
struct PacketRaysIn {
    const double* origin[3];
    const double* dir[3];
    const double* lo;
    const double* hi;
    std::size_t count = 0;
};

/// What Renderer::Impl::span_of (without cropping or clipping planes),
/// integrate_point_sampled's grid and RunFinder's constructor and
/// forward_walk compute for each ray, lane by lane with the same operations:
/// out[k] and octant[k] for each ray k that meets the volume (meets[k] = 1;
/// 0 where span_of gives none).
void prepare_packet_rays(const PacketFrame& frame, const PacketRaysIn& in, PacketRay* out, int* octant,
                         std::uint8_t* meets);

/// Pre-integration in packets: each lane samples its own ray's segment
/// ends (PacketRay's grid with offset 0: end e is sample e + 1, ends 0..n)
/// where a segment has an end in a non-empty macrocell, and pre-integrates
/// the segments between consecutive ends of its ray (as
/// integrate_preintegrated's windows do); those that are not (1, 0) are
/// packed with other lanes' into whole vectors (preintegrate_pack:
/// preintegrate_batch's operations lane by lane) and composited in each
/// lane's order, so the same bits. Only where empty macrocells join
/// (EmptySpace::joins_empty: a segment whose two ends lie in empty
/// macrocells is then (1, 0)), or where none is empty.
struct PacketPreint {
    Model model = Model::emission_absorption;
    bool full = true;  // `preintegrated` (else `preintegrated-simple`)
    /// preintegrate_scalar's segment (vf → vb over delta) where
    /// preintegrate_pack leaves one to the scalar code.
    void (*scalar)(const void* ctx, double vf, double vb, double delta, double* t,
                   double* radiance) = nullptr;
    const void* ctx = nullptr;
};

/// Traces rays[0..count) (see PacketRay) under src's rule and model (or,
/// with `pre`, pre-integrated) with front-to-back compositing, early
/// termination below `termination` and background `bg`: out[k] is ray k's
/// result, as composite() would give it; with `depth` (point rules only),
/// also its depths, as composite()'s DepthTrack would give them.
void trace_packets(const BatchSource& src, const PacketWalk& walk, const PacketRay* rays, std::size_t count,
                   double termination, const double* bg, PacketResult* out, const PacketPreint* pre = nullptr,
                   bool depth = false);

/// ShadedScalarMedium::factors (on-the-fly gradients, BatchSource::shade)
/// at points j0 .. j0 + count − 1 of `ray` (count ≤ kBatch), per lane.
struct ShadeBatch {
    alignas(64) double diffuse[3][kBatch];
    alignas(64) double specular[3][kBatch];
    alignas(64) double opacity[kBatch];
};

/// Fills `out` with the factors at points j0 .. j0 + count − 1 of `ray`
/// (whole vectors), leaving out vectors whose every lane has its bit set in
/// `skip`; the same bits as ShadedScalarMedium::factors.
void shade_batch(const BatchSource& src, const RayGrid& ray, std::int64_t j0, int count, std::uint32_t skip,
                 ShadeBatch& out);

/// The name of the target classify_batch dispatches to now (e.g. "AVX2").
std::string active_target();
/// Whether the kernels of that target fuse their multiply–adds (built with
/// FATHOM_SIMD_FMA, on a target with FMA: AVX2 and up): their lanes then
/// agree with the scalar code to a few ulp per operation instead of bit
/// for bit (exp_neg-inl.h's Fma).
bool fused_lanes();
/// Every target compiled in and supported by this CPU (bit masks of
/// Highway's target enum), for tests that force each in turn.
std::vector<std::int64_t> available_targets();
/// Forces one target (0: back to the best supported).
void force_target(std::int64_t target);

}  // namespace fathom::simd
