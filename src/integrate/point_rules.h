// The point-sampled quadratures' segment rules (SPEC §5), given σ_a and g
// after the model: riemann's (e^{−σδ}, g·δ) and alpha's (1 − α, g·w) with
// α = 1 − e^{−σδ} and w = α/σ (δ where σ = 0). The exponentials are
// exp_neg.h's, so that the SIMD classifier's lanes (simd_classify.cpp, which
// repeats these operations in this order) give the same bits.
#pragma once

#include "integrate/accumulator.h"
#include "integrate/exp_neg.h"

namespace fathom {

/// `riemann`: t = e^{−σ_a δ}, G = g·δ.
inline Segment riemann_segment(const MediumSample& m, double delta) {
    Segment seg{m.sigma == 0.0 ? 1.0 : preint::exp_neg(m.sigma * delta), {}};  // e^{−0} = 1: the same bits
    for (int c = 0; c < 3; ++c) seg.radiance[c] = m.source[c] * delta;
    return seg;
}

/// `alpha` (the NeRF quadrature, eq. (12)): the exact integral of the
/// segment's constant medium, g·(1 − e^{−σδ})/σ (g·δ where σ = 0).
inline Segment alpha_segment(const MediumSample& m, double delta) {
    if (m.sigma == 0.0) {  // the same bits as below (1 − e^{−0} = 0, weight δ) without the polynomial
        Segment seg{1.0, {}};
        for (int c = 0; c < 3; ++c) seg.radiance[c] = m.source[c] * delta;
        return seg;
    }
    const double alpha = preint::one_minus_exp_neg(m.sigma * delta);  // α_i = 1 − e^{−σδ}
    const double weight = m.sigma > 0.0 ? alpha / m.sigma : delta;    // (1 − e^{−σδ})/σ
    // t_i = 1 − α_i: within half an ulp of 1 of e^{−σδ} (absolute), which
    // is all T and the image see, for one exponential instead of two.
    Segment seg{1.0 - alpha, {}};
    for (int c = 0; c < 3; ++c) seg.radiance[c] = m.source[c] * weight;
    return seg;
}

}  // namespace fathom
