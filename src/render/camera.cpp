// Ray generation, SPEC §4.
#include "fathom/camera.h"

#include <cmath>
#include <numbers>

#include "fathom/error.h"

namespace fathom {

Camera Camera::look_at(const Vec3& position, const Vec3& target, const Vec3& up_hint) {
    const Vec3 f = target - position;
    if (length(f) == 0.0) throw Error("camera", "'position' and 'look_at' are the same point");
    Camera c;
    c.position = position;
    c.forward = normalize(f);
    const Vec3 r = cross(c.forward, up_hint);
    if (length(r) < 1e-12 * length(up_hint) || length(up_hint) == 0.0)
        throw Error("camera", "'up' is zero or parallel to the viewing direction");
    c.right = normalize(r);
    c.up = cross(c.right, c.forward);
    return c;
}

Camera Camera::from_matrix(const std::array<double, 16>& m, const std::string& subject) {
    for (double x : m)
        if (!std::isfinite(x)) throw Error(subject, "'camera_to_world' contains a non-finite number");
    const Vec3 x{m[0], m[4], m[8]}, y{m[1], m[5], m[9]}, z{m[2], m[6], m[10]};
    const std::array<Vec3, 3> cols{x, y, z};
    for (int a = 0; a < 3; ++a)
        for (int b = 0; b < 3; ++b) {
            const double want = a == b ? 1.0 : 0.0;
            if (std::abs(dot(cols[a], cols[b]) - want) > 1e-3)
                throw Error(subject, "'camera_to_world' rotation is not orthonormal (|R^T R - I| > 1e-3)");
        }
    Camera c;
    c.position = {m[3], m[7], m[11]};
    c.forward = -z;  // eq.: f = -Z column, u = +Y column, r = +X column (SPEC §4)
    c.up = y;
    c.right = x;
    return c;
}

Camera Camera::orbit(double azimuth_deg, double elevation_deg, double distance, const Vec3& center,
                     double radius) {
    const double a = azimuth_deg * std::numbers::pi / 180.0;
    const double e = elevation_deg * std::numbers::pi / 180.0;
    const Vec3 dir{std::cos(e) * std::cos(a), std::cos(e) * std::sin(a), std::sin(e)};
    const Vec3 up{-std::sin(e) * std::cos(a), -std::sin(e) * std::sin(a), std::cos(e)};
    return look_at(center + dir * (distance * radius), center, up);
}

Camera Camera::turned(const Vec3& center, double degrees) const {
    const double a = degrees * std::numbers::pi / 180.0, ca = std::cos(a), sa = std::sin(a);
    auto rot = [&](const Vec3& v) { return Vec3{ca * v.x - sa * v.y, sa * v.x + ca * v.y, v.z}; };
    Camera r = *this;
    r.position = center + rot(position - center);
    r.forward = rot(forward);
    r.right = rot(right);
    r.up = rot(up);
    return r;
}

std::array<double, 16> Camera::to_matrix() const {
    return {right.x, up.x, -forward.x, position.x, right.y, up.y, -forward.y, position.y,
            right.z, up.z, -forward.z, position.z, 0.0,     0.0,  0.0,        1.0};
}

Ray Camera::generate(int px, int py, int width, int height_px) const {
    return PixelRays(*this, width, height_px)(px, py);
}

PixelRays::PixelRays(const Camera& camera, int width, int height)
    : c_(camera),
      width_(width),
      height_(height),
      aspect_(static_cast<double>(width) / height),
      tan_half_(camera.projection == Projection::perspective
                    ? std::tan(camera.fov_y_deg * std::numbers::pi / 360.0)
                    : 0.0) {}

Ray PixelRays::operator()(int px, int py) const {
    const double x = (2.0 * (px + 0.5) / width_ - 1.0) * aspect_;
    const double y = 1.0 - 2.0 * (py + 0.5) / height_;
    if (c_.projection == Projection::perspective)
        return {c_.position, normalize(c_.forward + c_.right * (x * tan_half_) + c_.up * (y * tan_half_))};
    return {c_.position + (c_.right * x + c_.up * y) * (c_.height / 2.0), c_.forward};
}

}  // namespace fathom
