// Scene files (SPEC §7): parsing, overrides of header placement, errors.
#include <fstream>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/scene.h"

#include "test_util.h"

using namespace fathom;
using fathom::test::TempDir;

namespace {

void write(const std::filesystem::path& p, const std::string& text) {
    std::ofstream(p) << text;
}

// An 4×3×2 uint8 raw file with values 0..23.
std::filesystem::path raw_volume(const TempDir& d) {
    const auto p = d / "v.raw";
    std::ofstream out(p, std::ios::binary);
    for (int i = 0; i < 24; ++i) out.put(static_cast<char>(i));
    return p;
}

std::string scene_with(const std::string& volume, const std::string& extra = "") {
    return R"({"format": "fathom-scene/1", "volume": )" + volume +
           R"(, "transfer_function": {"format": "fathom-tf/1", "color": [[0, 1, 1, 1]], "opacity": [[0, 0], [23, 0.5]]})" +
           extra + "}";
}

std::string error_of(const std::string& text, const std::filesystem::path& base) {
    try {
        parse_scene(text, base, "scene.json");
    } catch (const Error& e) {
        return e.what();
    }
    return "";
}

}  // namespace

TEST(Scene, RawVolumeWithRelativePathAndPlacement) {
    TempDir d;
    raw_volume(d);
    write(d / "scene.json", scene_with(R"({"path": "v.raw", "dims": [4, 3, 2], "dtype": "uint8",
        "spacing": [0.5, 1, 2], "origin": [1, 2, 3]})",
                                       R"(, "render": {"width": 8, "height": 6, "integrator": "riemann",
        "sample_point": "mid", "step": 0.25, "step_unit": "world", "order": "back-to-front", "termination": 0,
        "background": [0.1, 0.2, 0.3], "model": "absorption"}, "camera": {"orbit": {"azimuth": 10, "elevation": 5}})"));
    const Scene sc = load_scene(d / "scene.json");
    EXPECT_EQ(sc.volume.dims()[0], 4);
    EXPECT_DOUBLE_EQ(sc.volume.value(3, 2, 1), 23.0);
    EXPECT_DOUBLE_EQ(sc.volume.spacing().z, 2.0);
    EXPECT_DOUBLE_EQ(sc.volume.origin().y, 2.0);
    EXPECT_EQ(sc.settings.width, 8);
    EXPECT_EQ(sc.settings.integrator, IntegratorKind::riemann);
    EXPECT_EQ(sc.settings.sample_point, SamplePoint::mid);
    EXPECT_TRUE(sc.settings.step_world);
    EXPECT_EQ(sc.settings.order, Order::back_to_front);
    EXPECT_EQ(sc.settings.model, Model::absorption);
    EXPECT_DOUBLE_EQ(sc.settings.background_radiance()[2], 0.3);
    const Image img = sc.renderer().render(sc.camera);
    EXPECT_EQ(img.width, 8);
}

TEST(Scene, DefaultsFollowTheContract) {
    TempDir d;
    raw_volume(d);
    const Scene sc =
        parse_scene(scene_with(R"({"path": "v.raw", "dims": [4, 3, 2], "dtype": "uint8"})"), d.path(), "s");
    EXPECT_EQ(sc.settings.width, 512);
    EXPECT_EQ(sc.settings.height, 512);
    EXPECT_EQ(sc.settings.model, Model::emission_absorption);
    EXPECT_DOUBLE_EQ(sc.settings.step, 0.5);
    EXPECT_DOUBLE_EQ(sc.settings.termination, 1e-3);
    EXPECT_EQ(sc.settings.background_radiance(), (Rgb{0, 0, 0}));
    RenderSettings s = sc.settings;
    s.model = Model::absorption;  // white under absorption, also when the model comes later
    EXPECT_EQ(s.background_radiance(), (Rgb{1, 1, 1}));
    // orthographic height defaults to 2R
    const Scene o = parse_scene(
        scene_with(
            R"({"path": "v.raw", "dims": [4, 3, 2], "dtype": "uint8"})",
            R"(, "camera": {"projection": "orthographic", "position": [0, -9, 0], "look_at": [0, 0, 0]})"),
        d.path(), "s");
    EXPECT_NEAR(o.camera.height, 2 * volume_bounds(o.volume).radius, 1e-12);
    EXPECT_NEAR(o.camera.up.z, 1.0, 1e-12);  // up defaults to +z
}

TEST(Scene, PresetAndTfFileAndPreclassified) {
    TempDir d;
    raw_volume(d);
    const Scene p = parse_scene(R"({"format": "fathom-scene/1", "volume": {"path": "v.raw", "dims": [4, 3, 2],
        "dtype": "uint8"}, "transfer_function": {"preset": "ct-bone"}})",
                                d.path(), "s");
    EXPECT_EQ(p.tf.name, "ct-bone");
    write(d / "tf.json", R"({"format": "fathom-tf/1", "color": [[0, 1, 1, 1]], "extinction": [[0, 2]]})");
    const Scene t = parse_scene(R"({"format": "fathom-scene/1", "volume": {"path": "v.raw", "dims": [4, 3, 2],
        "dtype": "uint8"}, "transfer_function": {"path": "tf.json"}})",
                                d.path(), "s");
    EXPECT_EQ(t.tf.alpha_kind, TransferFunction::Alpha::extinction);
}

TEST(Scene, ErrorsNameTheSceneAndTheProblem) {
    TempDir d;
    raw_volume(d);
    const std::string vol = R"({"path": "v.raw", "dims": [4, 3, 2], "dtype": "uint8"})";
    const std::vector<std::pair<std::string, std::string>> cases = {
        {scene_with(vol, R"(, "extra": 1)"), "unknown key 'extra'"},
        {scene_with(vol, R"(, "render": {"widht": 3})"), "unknown key 'widht'"},
        {scene_with(vol, R"(, "render": {"width": 0})"), "width"},
        {scene_with(vol, R"(, "render": {"step": -1})"), "step"},
        {scene_with(vol, R"(, "render": {"termination": 1})"), "termination"},
        {scene_with(vol, R"(, "render": {"integrator": "simpson"})"), "unknown integrator 'simpson'"},
        {scene_with(vol, R"(, "render": {"background": "pink"})"), "background"},
        {scene_with(vol, R"(, "camera": {"orbit": {"azimuth": 3}})"), "elevation"},
        {scene_with(vol, R"(, "camera": {"orbit": {"azimuth": 3, "elevation": 1}, "position": [1, 2, 3]})"),
         "exactly one"},
        {scene_with(
             vol,
             R"(, "camera": {"camera_to_world": [[1, 0, 0, 0], [0, 1, 0, 0], [0, 0, 2, 0], [0, 0, 0, 1]]})"),
         "orthonormal"},
        {scene_with(vol, R"(, "camera": {"position": [1, 1, 1], "look_at": [1, 1, 1]})"), "same point"},
        {scene_with(R"({"path": "v.raw", "dims": [4, 3, 2]})"), "dtype"},
        {scene_with(R"({"path": "v.raw", "dims": [4, 3, 2], "dtype": "uint8", "spacing": [1, 0, 1]})"),
         "spacing"},
        {R"({"format": "fathom-scene/2"})", "fathom-scene/1"},
        {R"({"format": "fathom-scene/1", "volume": )" + vol + "}", "transfer_function"},
        {R"({"format": "fathom-scene/1", "volume": {"density": "a.nrrd"}})", "both"},
        {"{\"format\": ", "invalid JSON"},
    };
    for (const auto& [text, needle] : cases) {
        const std::string msg = error_of(text, d.path());
        EXPECT_NE(msg.find("scene.json"), std::string::npos) << text << " -> " << msg;
        EXPECT_NE(msg.find(needle), std::string::npos) << text << " -> " << msg;
    }
    // a missing volume file names that file
    const std::string missing =
        error_of(scene_with(R"({"path": "nothere.raw", "dims": [4, 3, 2], "dtype": "uint8"})"), d.path());
    EXPECT_NE(missing.find("nothere.raw"), std::string::npos) << missing;
}

TEST(Scene, ExampleScenesLoadAndRender) {
    for (const char* name : {"lidc2-bone.json", "lidc2-spike.json"}) {
        Scene sc = load_scene(fathom::test::source_dir() / "examples" / name);
        sc.settings.width = sc.settings.height = 8;
        const Image img = sc.renderer().render(sc.camera);
        float sum = 0;
        for (float v : img.rgba) sum += v;
        EXPECT_GT(sum, 0.0f) << name;
    }
}

TEST(Scene, JitterKeys) {
    TempDir d;
    raw_volume(d);
    const std::string vol = R"({"path": "v.raw", "dims": [4, 3, 2], "dtype": "uint8"})";
    const Scene sc =
        parse_scene(scene_with(vol, R"(, "render": {"jitter": true, "jitter_seed": 12})"), d.path(), "s");
    EXPECT_TRUE(sc.settings.jitter);
    EXPECT_EQ(sc.settings.jitter_seed, 12u);
    EXPECT_NE(error_of(scene_with(vol, R"(, "render": {"jitter": 1})"), d.path()).find("jitter"),
              std::string::npos);
    EXPECT_NE(error_of(scene_with(vol, R"(, "render": {"jitter_seed": -1})"), d.path()).find("jitter_seed"),
              std::string::npos);
}

TEST(Scene, CropAndClipPlaneKeys) {
    TempDir d;
    raw_volume(d);
    const std::string vol = R"({"path": "v.raw", "dims": [4, 3, 2], "dtype": "uint8"})";
    const Scene sc = parse_scene(scene_with(vol, R"(, "render": {"crop": {"min": [0, 0, 0], "max": [2, 2, 1]},
                   "clip_planes": [{"point": [1, 1, 0.5], "normal": [0, 0, 1]}]})"),
                                 d.path(), "s");
    ASSERT_TRUE(sc.settings.crop.has_value());
    EXPECT_DOUBLE_EQ(sc.settings.crop->max.x, 2.0);
    ASSERT_EQ(sc.settings.clip_planes.size(), 1u);
    EXPECT_DOUBLE_EQ(sc.settings.clip_planes[0].point.z, 0.5);
    EXPECT_NE(error_of(scene_with(vol, R"(, "render": {"crop": {"min": [0, 0, 0]}})"), d.path()).find("crop"),
              std::string::npos);
    EXPECT_NE(
        error_of(
            scene_with(vol, R"(, "render": {"clip_planes": [{"point": [0, 0, 0], "normal": [0, 0, 0]}]})"),
            d.path())
            .find("clipping plane"),
        std::string::npos);
    EXPECT_NE(error_of(scene_with(vol, R"(, "render": {"clip_planes": {"point": [0, 0, 0]}})"), d.path())
                  .find("clip_planes"),
              std::string::npos);
}

TEST(Scene, ShadingKeys) {
    TempDir d;
    raw_volume(d);
    const std::string vol = R"({"path": "v.raw", "dims": [4, 3, 2], "dtype": "uint8"})";
    EXPECT_TRUE(parse_scene(scene_with(vol, R"(, "render": {"shading": true})"), d.path(), "s")
                    .settings.shading.enabled);
    const Scene sc = parse_scene(scene_with(vol, R"(, "render": {"shading": {"ambient": 0.3, "shininess": 40,
                   "lights": [{"direction": [1, 0, 0], "color": [1, 0.5, 0.5]}, {"direction": [0, 0, -1]}]}})"),
                                 d.path(), "s");
    EXPECT_TRUE(sc.settings.shading.enabled);
    EXPECT_DOUBLE_EQ(sc.settings.shading.ambient, 0.3);
    EXPECT_DOUBLE_EQ(sc.settings.shading.diffuse, 0.7);
    EXPECT_DOUBLE_EQ(sc.settings.shading.shininess, 40);
    ASSERT_EQ(sc.settings.shading.lights.size(), 2u);
    EXPECT_DOUBLE_EQ(sc.settings.shading.lights[0].color[1], 0.5);
    EXPECT_DOUBLE_EQ(sc.settings.shading.lights[1].color[2], 1.0);
    EXPECT_NE(error_of(scene_with(vol, R"(, "render": {"shading": "yes"})"), d.path()).find("shading"),
              std::string::npos);
    EXPECT_NE(
        error_of(scene_with(vol, R"(, "render": {"shading": {"lights": [{"color": [1, 1, 1]}]}})"), d.path())
            .find("direction"),
        std::string::npos);
    EXPECT_NE(
        error_of(scene_with(vol, R"(, "render": {"shading": {"specular": -1}})"), d.path()).find("shading"),
        std::string::npos);
}

TEST(Scene, IsosurfaceKeys) {
    TempDir d;
    raw_volume(d);
    const std::string vol = R"({"path": "v.raw", "dims": [4, 3, 2], "dtype": "uint8"})";
    const Scene sc = parse_scene(
        scene_with(vol,
                   R"(, "render": {"model": "isosurface", "isosurfaces": [{"value": 3, "color": [1, 0, 0],
                   "opacity": 0.5}, {"value": 7}]})"),
        d.path(), "s");
    ASSERT_EQ(sc.settings.isosurfaces.size(), 2u);
    EXPECT_DOUBLE_EQ(sc.settings.isosurfaces[0].opacity, 0.5);
    EXPECT_DOUBLE_EQ(sc.settings.isosurfaces[1].value, 7);
    EXPECT_NE(error_of(scene_with(vol, R"(, "render": {"model": "isosurface"})"), d.path()).find("iso"),
              std::string::npos);
    EXPECT_NE(error_of(scene_with(vol, R"(, "render": {"isosurfaces": [{"color": [1, 1, 1]}]})"), d.path())
                  .find("value"),
              std::string::npos);
}

TEST(Scene, OverridesReplaceOnlyWhatIsSet) {
    RenderSettings s;
    s.step = 0.25;
    s.clip_planes.push_back({{0, 0, 0}, {1, 0, 0}});
    SceneOverrides o;
    o.width = 32;
    o.integrator = "alpha";
    o.step_unit = "world";
    o.isos = {{5}, {7, 1, 0, 0, 0.5}};
    o.background = {0.1, 0.2, 0.3};
    apply_overrides(s, o, "test");
    EXPECT_EQ(s.width, 32);
    EXPECT_EQ(s.height, 512);  // not set: kept
    EXPECT_DOUBLE_EQ(s.step, 0.25);
    EXPECT_TRUE(s.step_world);
    EXPECT_EQ(s.integrator, IntegratorKind::alpha);
    EXPECT_EQ(s.model, Model::isosurface);  // isosurfaces select the model unless it is given
    ASSERT_EQ(s.isosurfaces.size(), 2u);
    EXPECT_DOUBLE_EQ(s.isosurfaces[1].opacity, 0.5);
    EXPECT_EQ(s.clip_planes.size(), 1u);  // none given: the scene's kept
    EXPECT_EQ(s.background_radiance(), (Rgb{0.1, 0.2, 0.3}));
    SceneOverrides t;
    t.transparent = true;
    apply_overrides(s, t, "test");
    EXPECT_TRUE(s.transparent);
}

TEST(Scene, OverrideErrorsNameTheFlag) {
    const auto error_of = [](const SceneOverrides& o) {
        RenderSettings s;
        try {
            apply_overrides(s, o, "subject");
        } catch (const Error& e) {
            EXPECT_EQ(e.subject() == "subject" || e.subject() == "render settings", true) << e.what();
            return e.reason();
        }
        return std::string();
    };
    SceneOverrides o;
    o.crop = {1, 2, 3};
    EXPECT_NE(error_of(o).find("--crop expects"), std::string::npos);
    o = {};
    o.clip_planes = {{0, 0, 0, 1, 0, 0}, {1}};
    EXPECT_NE(error_of(o).find("--clip-plane"), std::string::npos);
    o = {};
    o.step_unit = "furlong";
    EXPECT_NE(error_of(o).find("--step-unit"), std::string::npos);
    o = {};
    o.integrator = "simpson";
    EXPECT_NE(error_of(o).find("simpson"), std::string::npos);
    o = {};
    o.step = -1;
    EXPECT_NE(error_of(o).find("step"), std::string::npos);
    o = {};
    o.background = {1, 1};
    EXPECT_NE(error_of(o).find("--background"), std::string::npos);
}
