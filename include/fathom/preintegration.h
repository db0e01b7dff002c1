// Pre-integration tables (docs/theory.md eqs. (15)–(17)): a segment's
// opacity α and radiance C as a function of the scalar at its camera-side
// end (v_front) and far end (v_back), for one segment length δ. The renderer
// evaluates these integrals exactly per segment; the table is for looking at
// a transfer function (`fathom tf-table`) and for tools.
#pragma once

#include <vector>

#include "fathom/transfer_function.h"

namespace fathom {

struct PreintegrationTable {
    int size = 0;  // size × size entries
    double v_lo = 0,
           v_hi = 1;  // entry (i, j): v_front = v_lo + i·(v_hi − v_lo)/(size − 1), v_back likewise with j
    double delta = 1;  // segment length (world units)
    bool self_attenuation = true;
    std::vector<float> alpha;  // size², index i + size·j
    std::vector<float> color;  // size² × 3: C (radiance, premultiplied by the segment's coverage)

    [[nodiscard]] double v(int i) const { return v_lo + (v_hi - v_lo) * i / (size - 1); }
};

/// Builds the table exactly in O(size²) segment integrals (each entry is
/// composed from the grid cells its ramp crosses), over `threads` threads (0:
/// all cores). Throws Error on size < 2, v_hi ≤ v_lo or δ ≤ 0.
PreintegrationTable build_preintegration_table(const Classifier& tf, double v_lo, double v_hi, int size,
                                               double delta, bool self_attenuation, int threads = 0);

/// The same table entry by entry (each entry's integrals evaluated on their
/// own): O(size² · pieces); the check for the fast build.
PreintegrationTable build_preintegration_table_direct(const Classifier& tf, double v_lo, double v_hi,
                                                      int size, double delta, bool self_attenuation);

}  // namespace fathom
