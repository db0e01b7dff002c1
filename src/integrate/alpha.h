// `alpha`: the NeRF quadrature, eq. (12). σ_a and g are held constant over
// each segment at its sample point; the segment's radiance is the exact
// integral of that constant medium: g·(1 − e^{−σδ})/σ (g·δ where σ = 0).
#pragma once

#include <cmath>

#include "integrate/point_sampled.h"

namespace fathom {

template <Model M, class Medium>
RayResult integrate_alpha(const Medium& medium, const RaySpan& span, const RenderSettings& s, double h,
                          const Rgb& bg, const Accel& acc) {
    return integrate_point_sampled<M>(medium, span, s, h, bg, acc, [](const MediumSample& m, double delta) {
        if (m.sigma == 0.0) {  // the same bits as below (e^{−0} = 1, weight δ) without the libm calls
            Segment seg{1.0, {}};
            for (int c = 0; c < 3; ++c) seg.radiance[c] = m.source[c] * delta;
            return seg;
        }
        const double alpha = -std::expm1(-m.sigma * delta);             // α_i = 1 − e^{−σδ}
        const double weight = m.sigma > 0.0 ? alpha / m.sigma : delta;  // (1 − e^{−σδ})/σ
        // t_i = 1 − α_i: within half an ulp of 1 of e^{−σδ} (absolute), which
        // is all T and the image see, for one libm call instead of two.
        Segment seg{1.0 - alpha, {}};
        for (int c = 0; c < 3; ++c) seg.radiance[c] = m.source[c] * weight;
        return seg;
    });
}

}  // namespace fathom
