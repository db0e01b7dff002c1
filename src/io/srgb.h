// sRGB 8-bit encoding of linear radiance (IEC 61966-2-1), shared by the PNG
// and video writers.
#pragma once

#include <algorithm>
#include <cmath>
#include <cstdint>

namespace fathom::io {

/// Clamps to [0, 1]; NaN → 0.
inline double clamp01(float v) {
    return v > 0.0f ? std::min(static_cast<double>(v), 1.0) : 0.0;
}

/// IEC 61966-2-1 transfer function, linear → encoded, v in [0, 1].
inline double srgb_encode(double v) {
    return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

/// Rounds to the nearest code (halves up, like ⌊255·v + 0.5⌋), v in [0, 1].
inline std::uint8_t to_u8(double v01) {
    return static_cast<std::uint8_t>(std::lround(v01 * 255.0));
}

/// A linear radiance value as an sRGB 8-bit code.
inline std::uint8_t srgb8(float linear) {
    return to_u8(srgb_encode(clamp01(linear)));
}

}  // namespace fathom::io
