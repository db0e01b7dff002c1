// describe_volume: the text that `fathom info FILE` prints about a volume.
#pragma once

#include <string>

#include "fathom/volume.h"

namespace fathom {

/// A multi-line, 80-column summary: file name, dims, components, type,
/// spacing (column lengths of M), origin, the axis directions when M is not
/// diagonal, world extent, value range, memory size and a 16-bin histogram
/// of the samples (all components) drawn with '#'.
std::string describe_volume(const Volume& v, const std::string& name);

}  // namespace fathom
