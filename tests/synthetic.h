// Synthetic volumes and transfer functions for analytic tests.
#pragma once

#include <functional>
#include <string>

#include "fathom/camera.h"
#include "fathom/render.h"
#include "fathom/transfer_function.h"
#include "fathom/volume.h"

namespace fathom::test {

/// A float32 volume of n³ nodes, spacing s, origin 0, v(i, j, k) = f(i, j, k).
inline Volume make_volume(std::int64_t nx, std::int64_t ny, std::int64_t nz,
                          const std::function<double(double, double, double)>& f, double spacing = 1.0) {
    Volume v({nx, ny, nz}, DType::f32);
    v.set_spacing({spacing, spacing, spacing});
    for (std::int64_t k = 0; k < nz; ++k)
        for (std::int64_t j = 0; j < ny; ++j)
            for (std::int64_t i = 0; i < nx; ++i)
                v.set_value(i, j, k,
                            f(static_cast<double>(i), static_cast<double>(j), static_cast<double>(k)));
    return v;
}

/// A TF with extinction σ(v) = points and a single constant color.
inline TransferFunction extinction_tf(std::vector<std::pair<double, double>> sigma, Rgb color) {
    TransferFunction tf;
    tf.alpha_kind = TransferFunction::Alpha::extinction;
    tf.alpha_points = std::move(sigma);
    tf.color_points = {{0.0, color}};
    return tf;
}

/// Cameras for comparing renders: two axis-aligned views (rays along
/// macrocell faces), an oblique one at `oblique` half diagonals, and an
/// orthographic one from above.
inline std::vector<Camera> comparison_cameras(const Volume& v, double oblique = 2.2) {
    const Bounds b = volume_bounds(v);
    std::vector<Camera> c{Camera::orbit(0, 0, 2.5, b.center, b.radius),
                          Camera::orbit(90, 0, 2.5, b.center, b.radius),
                          Camera::orbit(33, 27, oblique, b.center, b.radius)};
    Camera o = Camera::orbit(0, 90 - 1e-9, 3, b.center, b.radius);
    o.projection = Projection::orthographic;
    o.height = 2 * b.radius;
    c.push_back(o);
    return c;
}

}  // namespace fathom::test
