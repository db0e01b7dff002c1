// Highway's foreach_target: compiled once per x86 target, project_boxes
// dispatched at run time (src/render/simd_bounds.h). Lanes are boxes; each
// performs the scalar projection's operations in its order, without fused
// multiply–add.
#include "render/simd_bounds.h"

#include <algorithm>

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

}  // namespace fathom::simd
#endif
