// Highway's foreach_target: compiled once per x86 target, project_boxes
// dispatched at run time (src/render/simd_bounds.h). Lanes are boxes; each
// performs the scalar projection's operations in its order, without fused
// multiply–add.
#include "render/simd_bounds.h"

#include <algorithm>
#include <limits>

#undef HWY_TARGET_INCLUDE
#define HWY_TARGET_INCLUDE "render/simd_bounds.cpp"
#include <hwy/foreach_target.h>  // IWYU pragma: keep
#include <hwy/highway.h>

HWY_BEFORE_NAMESPACE();
namespace fathom::simd {
namespace HWY_NAMESPACE {
namespace hn = hwy::HWY_NAMESPACE;

void ProjectBoxes(const BoxProjection& p, const std::uint32_t* index, std::size_t count,
                  const BoxImages& out) {
    using D = hn::ScalableTag<double>;
    using V = hn::Vec<D>;
    const D d;
    const std::size_t N = hn::Lanes(d);
    const V zero = hn::Zero(d), half = hn::Set(d, 0.5), inf = hn::Set(d, INFINITY);
    const V margin = hn::Set(d, p.margin),
            edge_len = hn::Set(d, static_cast<double>(std::int64_t{1} << p.shift));
    const V sx = hn::Set(d, p.scale_x), sy = hn::Set(d, p.scale_y), bx = hn::Set(d, p.bx),
            by = hn::Set(d, p.by);
    struct V3 {
        V x, y, z;
    };
    auto add = [](const V3& a, const V3& b) {
        return V3{hn::Add(a.x, b.x), hn::Add(a.y, b.y), hn::Add(a.z, b.z)};
    };
    auto dot = [](const V3& a) {
        return hn::Add(hn::Add(hn::Mul(a.x, a.x), hn::Mul(a.y, a.y)), hn::Mul(a.z, a.z));
    };
    auto scaled = [&](const Vec3& c, V s) {  // col[a]·s
        return V3{hn::Mul(hn::Set(d, c.x), s), hn::Mul(hn::Set(d, c.y), s), hn::Mul(hn::Set(d, c.z), s)};
    };
    for (std::size_t b = 0; b < count; b += N) {
        HWY_ALIGN double at[hn::MaxLanes(d)];
        for (std::size_t l = 0; l < N; ++l) at[l] = static_cast<double>(index[std::min(b + l, count - 1)]);
        // the macrocell per axis: exact (the index and the quotients stay below 2^32)
        V rest = hn::Load(d, at), m[3];
        for (int a = 0; a < 3; ++a) {
            const V n = hn::Set(d, static_cast<double>(p.dims[a]));
            const V q = hn::Floor(hn::Div(rest, n));
            m[a] = hn::Sub(rest, hn::Mul(q, n));
            rest = q;
        }
        V lo[3], hi[3];
        for (int a = 0; a < 3; ++a) {
            lo[a] = hn::Sub(hn::Mul(m[a], edge_len), margin);
            hi[a] = hn::Add(hn::Min(hn::Mul(hn::Add(m[a], hn::Set(d, 1.0)), edge_len),
                                    hn::Set(d, static_cast<double>(p.nodes[a] - 1))),
                            margin);
        }
        // corner k = the first + the edges whose bits k has
        V3 first{hn::Set(d, p.c0.x), hn::Set(d, p.c0.y), hn::Set(d, p.c0.z)};
        for (int a = 0; a < 3; ++a) first = add(first, scaled(p.col[static_cast<std::size_t>(a)], lo[a]));
        V3 edge[3];
        for (int a = 0; a < 3; ++a)
            edge[a] = scaled(p.col[static_cast<std::size_t>(a)], hn::Sub(hi[a], lo[a]));
        V x0 = inf, x1 = hn::Neg(inf), y0 = inf, y1 = hn::Neg(inf), z0 = inf, z1 = hn::Neg(inf), far2 = zero;
        for (int k = 0; k < 8; ++k) {
            V3 c = first;
            for (int a = 0; a < 3; ++a)
                if (((k >> a) & 1) != 0) c = add(c, edge[a]);
            const V s = p.perspective ? hn::Div(hn::Set(d, 1.0), c.z) : hn::Set(d, 1.0);
            const V px = hn::Add(hn::Mul(hn::Mul(c.x, s), sx), bx),
                    py = hn::Sub(by, hn::Mul(hn::Mul(c.y, s), sy));
            // std::min(a, b) is b < a ? b : a: IfThenElse keeps a NaN out as it does
            x0 = hn::IfThenElse(hn::Lt(px, x0), px, x0);
            x1 = hn::IfThenElse(hn::Lt(x1, px), px, x1);
            y0 = hn::IfThenElse(hn::Lt(py, y0), py, y0);
            y1 = hn::IfThenElse(hn::Lt(y1, py), py, y1);
            z0 = hn::IfThenElse(hn::Lt(c.z, z0), c.z, z0);
            z1 = hn::IfThenElse(hn::Lt(z1, c.z), c.z, z1);
            const V r2 = dot(c);
            far2 = hn::IfThenElse(hn::Lt(far2, r2), r2, far2);
        }
        V t0 = z0, t1 = z1;
        if (p.perspective) {
            V3 h = add(add(edge[0], edge[1]), edge[2]);
            h = V3{hn::Mul(h.x, half), hn::Mul(h.y, half), hn::Mul(h.z, half)};
            const V reach = hn::Sub(hn::Sqrt(dot(add(first, h))), hn::Sqrt(dot(h)));
            t0 = hn::IfThenElse(hn::Lt(z0, reach), reach, z0);  // std::max(z0, reach)
            t1 = hn::Sqrt(far2);
        }
        hn::StoreU(x0, d, out.x0 + b);
        hn::StoreU(x1, d, out.x1 + b);
        hn::StoreU(y0, d, out.y0 + b);
        hn::StoreU(y1, d, out.y1 + b);
        hn::StoreU(t0, d, out.t0 + b);
        hn::StoreU(t1, d, out.t1 + b);
    }
}

void ComputeFootprints(const FootprintRule& r, const BoxImages& in, std::size_t count,
                       const simd::Footprints& out) {
    using D = hn::ScalableTag<double>;
    using V = hn::Vec<D>;
    const D d;
    const hn::Rebind<float, D> df;
    const hn::Rebind<std::int32_t, D> di;
    const hn::Rebind<std::uint32_t, D> du;
    const std::size_t N = hn::Lanes(d);
    const V zero = hn::Zero(d), minus_one = hn::Set(d, -1.0), slack = hn::Set(d, r.pixel_slack),
            t_slack = hn::Set(d, r.t_slack);
    const V w = hn::Set(d, static_cast<double>(r.width)), h = hn::Set(d, static_cast<double>(r.height));
    const V w1 = hn::Set(d, static_cast<double>(r.width - 1)),
            h1 = hn::Set(d, static_cast<double>(r.height - 1));
    const auto fzero = hn::Zero(df);
    const hn::Rebind<std::uint64_t, D> dq;
    // a mask of doubles as one of the floats in the same lanes
    auto as_float = [&](hn::Mask<D> m) {
        return hn::MaskFromVec(hn::BitCast(df, hn::TruncateTo(du, hn::BitCast(dq, hn::VecFromMask(d, m)))));
    };
    const V fmax = hn::Set(d, static_cast<double>(std::numeric_limits<float>::max()));
    const auto finf = hn::Set(df, INFINITY), fbig = hn::Set(df, std::numeric_limits<float>::max());
    // round_float: the nearest float, then one step down (or up) where it
    // lies above (below) x: std::nextafter's bits (±0 step to ∓ the least
    // subnormal). Beyond the floats' range, where DemoteTo may saturate,
    // what the nearest float and the step give: down, FLT_MAX above it (∞
    // at ∞) and −∞ below; up, ∞ above and −FLT_MAX below (−∞ at −∞).
    auto rounded = [&](V x, bool down) {
        const auto f = hn::DemoteTo(df, x);
        const V back = hn::PromoteTo(d, f);
        const auto wrong = as_float(down ? hn::Lt(x, back) : hn::Lt(back, x));
        const auto bits = hn::BitCast(du, f);
        const auto one = hn::Set(du, 1u);
        const auto away = hn::Add(bits, one), toward = hn::Sub(bits, one);  // from zero, toward it
        const auto pos = hn::RebindMask(du, hn::Lt(fzero, f)), neg = hn::RebindMask(du, hn::Lt(f, fzero));
        const auto at_zero = hn::Set(du, down ? 0x80000001u : 0x00000001u);
        const auto stepped =
            hn::IfThenElse(pos, down ? toward : away, hn::IfThenElse(neg, down ? away : toward, at_zero));
        auto r = hn::IfThenElse(wrong, hn::BitCast(df, stepped), f);
        const auto above = as_float(hn::Lt(fmax, x)), below = as_float(hn::Lt(x, hn::Neg(fmax)));
        const auto infinite = as_float(hn::IsInf(x));
        if (down) {
            r = hn::IfThenElse(above, hn::IfThenElse(infinite, finf, fbig), r);
            return hn::IfThenElse(below, hn::Neg(finf), r);
        }
        r = hn::IfThenElse(below, hn::IfThenElse(infinite, hn::Neg(finf), hn::Neg(fbig)), r);
        return hn::IfThenElse(above, finf, r);
    };
    for (std::size_t b = 0; b < count; b += N) {
        const V x0 = hn::LoadU(d, in.x0 + b), x1 = hn::LoadU(d, in.x1 + b), y0 = hn::LoadU(d, in.y0 + b),
                y1 = hn::LoadU(d, in.y1 + b), t0 = hn::LoadU(d, in.t0 + b), t1 = hn::LoadU(d, in.t1 + b);
        const auto finite = hn::IsFinite(hn::Add(hn::Add(hn::Add(hn::Add(hn::Add(x0, x1), y0), y1), t0), t1));
        // max(0, clamp(v, −1, n)) = min(max(v, 0), n); min(n − 1, clamp(v, −1, n)) = max(min(v, n − 1), −1)
        const V rx0 = hn::Min(hn::Max(hn::Ceil(hn::Sub(x0, slack)), zero), w);
        const V rx1 = hn::Max(hn::Min(hn::Floor(hn::Add(x1, slack)), w1), minus_one);
        const V ry0 = hn::Min(hn::Max(hn::Ceil(hn::Sub(y0, slack)), zero), h);
        const V ry1 = hn::Max(hn::Min(hn::Floor(hn::Add(y1, slack)), h1), minus_one);
        hn::StoreU(hn::DemoteTo(di, hn::IfThenElse(finite, rx0, zero)), di, out.x0 + b);
        hn::StoreU(hn::DemoteTo(di, hn::IfThenElse(finite, rx1, w1)), di, out.x1 + b);
        hn::StoreU(hn::DemoteTo(di, hn::IfThenElse(finite, ry0, zero)), di, out.y0 + b);
        hn::StoreU(hn::DemoteTo(di, hn::IfThenElse(finite, ry1, h1)), di, out.y1 + b);
        const auto fin = as_float(finite);
        hn::StoreU(hn::IfThenElse(fin, rounded(hn::Sub(t0, t_slack), true), hn::Neg(finf)), df, out.lo + b);
        hn::StoreU(hn::IfThenElse(fin, rounded(hn::Add(t1, t_slack), false), finf), df, out.hi + b);
    }
}

void DrawFootprints(const simd::Footprints& f, std::size_t count, int width, float* lo, float* hi) {
    using DF = hn::ScalableTag<float>;
    const DF df;
    const auto NF = static_cast<std::int32_t>(hn::Lanes(df));
    for (std::size_t k = 0; k < count; ++k) {
        const std::int32_t x0 = f.x0[k], x1 = f.x1[k];
        if (x0 > x1) continue;
        const float flo = f.lo[k], fhi = f.hi[k];
        const auto vlo = hn::Set(df, flo), vhi = hn::Set(df, fhi);
        for (std::int32_t y = f.y0[k]; y <= f.y1[k]; ++y) {
            float* L = lo + static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
            float* H = hi + static_cast<std::size_t>(y) * static_cast<std::size_t>(width);
            std::int32_t x = x0;
            // std::min(a, b) = b < a ? b : a; std::max(a, b) = a < b ? b : a
            for (; x + NF <= x1 + 1; x += NF) {
                const auto a = hn::LoadU(df, L + x), c = hn::LoadU(df, H + x);
                hn::StoreU(hn::IfThenElse(hn::Lt(vlo, a), vlo, a), df, L + x);
                hn::StoreU(hn::IfThenElse(hn::Lt(c, vhi), vhi, c), df, H + x);
            }
            if (x > x1) continue;
            if (x + NF <= width) {  // the rest of the footprint's row in one vector within the image's row
                const auto in = hn::FirstN(df, static_cast<std::size_t>(x1 + 1 - x));
                const auto a = hn::LoadU(df, L + x), c = hn::LoadU(df, H + x);
                hn::StoreU(hn::IfThenElse(hn::And(in, hn::Lt(vlo, a)), vlo, a), df, L + x);
                hn::StoreU(hn::IfThenElse(hn::And(in, hn::Lt(c, vhi)), vhi, c), df, H + x);
                continue;
            }
            for (; x <= x1; ++x) {
                L[x] = std::min(L[x], flo);
                H[x] = std::max(H[x], fhi);
            }
        }
    }
}

// NOLINTNEXTLINE(google-readability-namespace-comments)
}  // namespace HWY_NAMESPACE
}  // namespace fathom::simd
HWY_AFTER_NAMESPACE();

#if HWY_ONCE
namespace fathom::simd {

HWY_EXPORT(ProjectBoxes);

void project_boxes(const BoxProjection& p, const std::uint32_t* index, std::size_t count,
                   const BoxImages& out) {
    HWY_DYNAMIC_DISPATCH(ProjectBoxes)(p, index, count, out);
}

HWY_EXPORT(ComputeFootprints);
HWY_EXPORT(DrawFootprints);

void footprints(const FootprintRule& r, const BoxImages& in, std::size_t count, const Footprints& out) {
    HWY_DYNAMIC_DISPATCH(ComputeFootprints)(r, in, count, out);
}

void draw_footprints(const Footprints& f, std::size_t count, int width, float* lo, float* hi) {
    HWY_DYNAMIC_DISPATCH(DrawFootprints)(f, count, width, lo, hi);
}

}  // namespace fathom::simd
#endif
