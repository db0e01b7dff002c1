#include "integrate/preintegrated.h"

#include "integrate/preint_piece.h"

namespace fathom::preint {

PieceIntegral integrate_piece(double len, double s0, double s1, const Quadratic& g, bool self_attenuation) {
    return integrate_piece_t<double>(len, s0, s1, g, self_attenuation);
}

}  // namespace fathom::preint
