// Cameras (SPEC §4): look-at, camera-to-world matrix and orbit forms, each
// perspective or orthographic. Pixel (px, py) of a W × H image (row 0 at the
// top) shoots through its centre.
#pragma once

#include <array>
#include <string>

#include "fathom/math.h"

namespace fathom {

enum class Projection { perspective, orthographic };

struct Ray {
    Vec3 origin;
    Vec3 dir;  // unit length
};

class Camera {
public:
    Projection projection = Projection::perspective;
    Vec3 position{0, 0, 0};
    Vec3 forward{0, 0, -1};   // f
    Vec3 right{1, 0, 0};      // r
    Vec3 up{0, 1, 0};         // u
    double fov_y_deg = 30.0;  // perspective
    double height = 2.0;      // orthographic: world units seen vertically

    /// f = normalize(look_at − position), r = normalize(f × up), u = r × f.
    /// Throws Error when position == look_at or up is parallel to f.
    static Camera look_at(const Vec3& position, const Vec3& target, const Vec3& up_hint);
    /// A 4×4 row-major camera-to-world matrix looking down −Z, +Y up, +X
    /// right; its upper 3×3 must be orthonormal within 1e−3 (else Error).
    static Camera from_matrix(const std::array<double, 16>& m, const std::string& subject = "camera");
    /// Orbit around centre c at k·R: azimuth and elevation in degrees.
    static Camera orbit(double azimuth_deg, double elevation_deg, double distance, const Vec3& center,
                        double radius);

    /// This camera turned by `degrees` about the vertical (+z) axis through
    /// `center` (turntables, benchmark frames).
    [[nodiscard]] Camera turned(const Vec3& center, double degrees) const;
    /// The 4×4 row-major camera-to-world matrix (from_matrix's inverse:
    /// columns right, up, −forward, position).
    [[nodiscard]] std::array<double, 16> to_matrix() const;

    /// The ray through the centre of pixel (px, py).
    [[nodiscard]] Ray generate(int px, int py, int width, int height_px) const;
};

/// The rays of Camera::generate for one width × height image (the same
/// bits), with what every pixel shares computed once.
class PixelRays {
public:
    PixelRays(const Camera& camera, int width, int height);
    [[nodiscard]] Ray operator()(int px, int py) const;

private:
    Camera c_;
    int width_, height_;
    double aspect_, tan_half_;  // tan(fov_y / 2): perspective
};

}  // namespace fathom
