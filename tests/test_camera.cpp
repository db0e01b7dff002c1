// Camera conventions (SPEC §4): a single bright voxel lands on the pixel an
// independent pinhole projection predicts, for each camera form.
#include <cmath>
#include <numbers>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/render.h"

#include "synthetic.h"

using namespace fathom;

namespace {

struct Pixel {
    int x, y;
};

// Projects world point p through a camera given by its frame (independent of Camera::generate).
Pixel project(const Vec3& p, const Vec3& pos, const Vec3& f, const Vec3& r, const Vec3& u, bool ortho,
              double fov_deg, double height, int W, int H) {
    const Vec3 v = p - pos;
    const double aspect = static_cast<double>(W) / H;
    double x, y;
    if (ortho) {
        x = dot(v, r) / (height / 2);
        y = dot(v, u) / (height / 2);
    } else {
        const double t = std::tan(fov_deg * std::numbers::pi / 360);
        x = dot(v, r) / dot(v, f) / t;
        y = dot(v, u) / dot(v, f) / t;
    }
    // x = (2(px + 0.5)/W − 1)·aspect, y = 1 − 2(py + 0.5)/H
    return {static_cast<int>(std::lround((x / aspect + 1) * W / 2 - 0.5)),
            static_cast<int>(std::lround((1 - y) * H / 2 - 0.5))};
}

Pixel brightest(const Image& img) {
    Pixel best{-1, -1};
    float v = -1;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x)
            if (img.pixel(x, y)[0] > v) v = img.pixel(x, y)[0], best = {x, y};
    return best;
}

struct Fixture {
    Volume vol = fathom::test::make_volume(
        9, 9, 9, [](double, double, double) { return 0.0; }, 0.5);
    TransferFunction tf;
    Vec3 voxel_world;
    Fixture() {
        vol.set_origin({-1.0, 2.0, 0.5});
        vol.set_value(6, 2, 5, 1.0);
        voxel_world = vol.index_to_world({6, 2, 5});
        tf.alpha_kind = TransferFunction::Alpha::extinction;
        tf.alpha_points = {{0.0, 0.0}};
        tf.color_points = {{0.0, {0, 0, 0}}, {1.0, {1, 1, 1}}};
    }
    Image render(const Camera& cam, int W, int H) const {
        RenderSettings s;
        s.width = W;
        s.height = H;
        s.model = Model::mip;
        s.step = 0.05;
        return Renderer(vol, tf, s).render(cam);
    }
};

}  // namespace

TEST(Camera, BrightVoxelLandsOnPredictedPixelForEveryForm) {
    const Fixture fx;
    const Bounds b = volume_bounds(fx.vol);
    const int W = 96, H = 64;
    for (bool ortho : {false, true}) {
        std::vector<std::pair<std::string, Camera>> cams;
        cams.emplace_back("look_at", Camera::look_at(b.center + Vec3{3.0, -4.0, 2.5}, b.center, {0, 0, 1}));
        cams.emplace_back("orbit", Camera::orbit(35, 20, 3, b.center, b.radius));
        cams.emplace_back("orbit-pole", Camera::orbit(10, 90, 3, b.center, b.radius));
        // camera_to_world: columns r, u, −f and the position
        const Camera la = Camera::look_at(b.center + Vec3{-4.0, 1.0, -2.0}, b.center, {0, 1, 0});
        const std::array<double, 16> m{la.right.x,
                                       la.up.x,
                                       -la.forward.x,
                                       la.position.x,
                                       la.right.y,
                                       la.up.y,
                                       -la.forward.y,
                                       la.position.y,
                                       la.right.z,
                                       la.up.z,
                                       -la.forward.z,
                                       la.position.z,
                                       0,
                                       0,
                                       0,
                                       1};
        cams.emplace_back("camera_to_world", Camera::from_matrix(m));
        for (auto& [name, cam] : cams) {
            cam.projection = ortho ? Projection::orthographic : Projection::perspective;
            cam.fov_y_deg = 40;
            cam.height = 2 * b.radius;
            const Pixel want = project(fx.voxel_world, cam.position, cam.forward, cam.right, cam.up, ortho,
                                       cam.fov_y_deg, cam.height, W, H);
            const Pixel got = brightest(fx.render(cam, W, H));
            EXPECT_LE(std::abs(got.x - want.x), 1) << name << (ortho ? " ortho" : " persp");
            EXPECT_LE(std::abs(got.y - want.y), 1) << name << (ortho ? " ortho" : " persp");
        }
    }
}

TEST(Camera, PixelCentresAndOrientation) {
    Camera c = Camera::look_at({0, 0, 0}, {0, 1, 0}, {0, 0, 1});
    // f = +y, r = f × up = +x, u = r × f = +z
    EXPECT_NEAR(c.right.x, 1, 1e-15);
    EXPECT_NEAR(c.up.z, 1, 1e-15);
    c.projection = Projection::orthographic;
    c.height = 2;
    // 2×2 image: pixel (0, 0) is the top-left: x = −0.5, y = +0.5
    const Ray r = c.generate(0, 0, 2, 2);
    EXPECT_NEAR(r.origin.x, -0.5, 1e-15);
    EXPECT_NEAR(r.origin.z, 0.5, 1e-15);
    // Orbit at elevation 90: up is the tangent −(cos a, sin a, 0)
    const Camera p = Camera::orbit(0, 90, 3, {0, 0, 0}, 1);
    EXPECT_NEAR(p.position.z, 3, 1e-12);
    EXPECT_NEAR(p.up.x, -1, 1e-12);
}

TEST(Camera, RejectsBadFrames) {
    EXPECT_THROW(Camera::look_at({0, 0, 0}, {0, 0, 0}, {0, 0, 1}), Error);
    EXPECT_THROW(Camera::look_at({0, 0, 0}, {0, 0, 1}, {0, 0, 1}), Error);
    std::array<double, 16> m{1, 0, 0, 0, 0, 1, 0, 0, 0, 0, 1.01, 0, 0, 0, 0, 1};
    EXPECT_THROW(Camera::from_matrix(m), Error);
    m[10] = 1.0004;  // |R^T R − I| = 8e−4, within 1e−3
    EXPECT_NO_THROW(Camera::from_matrix(m));
}
