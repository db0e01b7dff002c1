// The command line (SPEC §8): exit codes, no partial output, overrides,
// thread-count independence.
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "fathom/io.h"
#include "fathom/scene.h"
#include "fathom/video.h"

#include "test_util.h"

using fathom::test::TempDir;
namespace fs = std::filesystem;

namespace {

struct CliRun {
    int status;
    std::string err;
};

CliRun fathom_cli(const std::string& args, const TempDir& d) {
    const std::string errfile = (d / "stderr.txt").string();
    const std::string cmd = fathom::test::cli() + " " + args + " >/dev/null 2>" + errfile + " </dev/null";
    const int rc = std::system(cmd.c_str());
    std::ifstream in(errfile);
    std::stringstream ss;
    ss << in.rdbuf();
    return {WIFEXITED(rc) ? WEXITSTATUS(rc) : -1, ss.str()};
}

void write(const fs::path& p, const std::string& text) {
    std::ofstream(p) << text;
}

// A small smooth uint8 volume as raw + a scene over it.
void make_scene(const TempDir& d, const std::string& render = "") {
    std::ofstream out(d / "v_16x12x10_uint8.raw", std::ios::binary);
    for (int k = 0; k < 10; ++k)
        for (int j = 0; j < 12; ++j)
            for (int i = 0; i < 16; ++i) out.put(static_cast<char>((i * 13 + j * 7 + k * 29) % 200));
    out.close();
    write(d / "scene.json", R"({"format": "fathom-scene/1",
        "volume": {"path": "v_16x12x10_uint8.raw", "dims": [16, 12, 10], "dtype": "uint8"},
        "transfer_function": {"format": "fathom-tf/1", "color": [[0, 1, 0.5, 0], [200, 0, 0.5, 1]],
                              "opacity": [[0, 0], [100, 0.2], [200, 0.6]]},
        "camera": {"orbit": {"azimuth": 30, "elevation": 20}},
        "render": {"width": 40, "height": 30)" +
                                render + "}}");
}

std::vector<char> bytes(const fs::path& p) {
    std::ifstream in(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), {}};
}

}  // namespace

TEST(Cli, RendersASceneToEveryFormat) {
    TempDir d;
    make_scene(d);
    for (const char* ext : {"pfm", "png", "exr"}) {
        const fs::path out = d / (std::string("out.") + ext);
        const CliRun r = fathom_cli("render " + (d / "scene.json").string() + " -o " + out.string(), d);
        EXPECT_EQ(r.status, 0) << r.err;
        EXPECT_TRUE(fs::exists(out)) << ext;
    }
    const fathom::Image img = fathom::read_pfm(d / "out.pfm");
    EXPECT_EQ(img.width, 40);
    EXPECT_EQ(img.height, 30);
}

TEST(Cli, ThreadCountDoesNotChangeTheImage) {
    TempDir d;
    make_scene(d, R"(, "integrator": "riemann")");
    const std::string scene = (d / "scene.json").string();
    ASSERT_EQ(fathom_cli("render " + scene + " -o " + (d / "a.pfm").string() + " --threads 1", d).status, 0);
    ASSERT_EQ(fathom_cli("render " + scene + " -o " + (d / "b.pfm").string() + " --threads 2", d).status, 0);
    ASSERT_EQ(fathom_cli("render " + scene + " -o " + (d / "c.pfm").string() + " --threads 7", d).status, 0);
    EXPECT_EQ(bytes(d / "a.pfm"), bytes(d / "b.pfm"));
    EXPECT_EQ(bytes(d / "a.pfm"), bytes(d / "c.pfm"));
}

TEST(Cli, FlagsOverrideTheScene) {
    TempDir d;
    make_scene(d);
    const std::string scene = (d / "scene.json").string();
    ASSERT_EQ(fathom_cli("render " + scene + " -o " + (d / "a.pfm").string() +
                             " --width 12 --height 9 --model absorption --integrator reference --step 1 "
                             "--order back-to-front --termination 0",
                         d)
                  .status,
              0);
    const fathom::Image img = fathom::read_pfm(d / "a.pfm");
    EXPECT_EQ(img.width, 12);
    EXPECT_EQ(img.height, 9);
    // absorption with the default white background: corners miss the box and are white
    EXPECT_FLOAT_EQ(img.pixel(0, 0)[0], 1.0f);
}

TEST(Cli, NoSceneFormWithPreset) {
    TempDir d;
    make_scene(d);
    const CliRun r = fathom_cli("render --volume " + (d / "v_16x12x10_uint8.raw").string() +
                                    " --preset ct-bone --orbit 30,20,2.5 --width 16 --height 16 -o " +
                                    (d / "a.png").string(),
                                d);
    EXPECT_EQ(r.status, 0) << r.err;
    EXPECT_TRUE(fs::exists(d / "a.png"));
}

TEST(Cli, UsageErrorsExitTwo) {
    TempDir d;
    make_scene(d);
    const std::string scene = (d / "scene.json").string();
    EXPECT_EQ(fathom_cli("", d).status, 2);
    EXPECT_EQ(fathom_cli("render " + scene, d).status, 2);  // no -o
    EXPECT_EQ(fathom_cli("render " + scene + " -o x.pfm --width abc", d).status, 2);
    EXPECT_EQ(fathom_cli("render " + scene + " -o x.pfm --bogus", d).status, 2);
    EXPECT_EQ(fathom_cli("render " + scene + " -o x.txt", d).status, 2);
    EXPECT_EQ(fathom_cli("render " + scene + " -o x.pfm --integrator simpson", d).status, 2);
    EXPECT_EQ(fathom_cli("render -o x.pfm", d).status, 2);
    EXPECT_EQ(fathom_cli("render --volume v.raw -o x.pfm", d).status, 2);  // no --tf/--preset
    EXPECT_EQ(fathom_cli("frobnicate", d).status, 2);
    EXPECT_FALSE(fs::exists("x.pfm"));
    EXPECT_EQ(fathom_cli("--help", d).status, 0);
    EXPECT_EQ(fathom_cli("render --help", d).status, 0);
    EXPECT_EQ(fathom_cli("--version", d).status, 0);
}

TEST(Cli, BadInputExitsOneWithOneMessageAndNoOutput) {
    TempDir d;
    make_scene(d);
    const fs::path out = d / "out.pfm";
    write(d / "broken.json", R"({"format": "fathom-scene/1", "volume": )");
    write(d / "badtf.json",
          R"({"format": "fathom-scene/1", "volume": {"path": "v_16x12x10_uint8.raw", "dims": [16, 12, 10],
        "dtype": "uint8"}, "transfer_function": {"format": "fathom-tf/1", "color": [[0, 1, 1, 1]], "opacity": [[5, 0], [1, 1]]}})");
    write(d / "short.json",
          R"({"format": "fathom-scene/1", "volume": {"path": "v_16x12x10_uint8.raw", "dims": [16, 12, 11],
        "dtype": "uint8"}, "transfer_function": {"preset": "grayscale"}})");
    write(
        d / "huge.json",
        R"({"format": "fathom-scene/1", "volume": {"path": "v_16x12x10_uint8.raw", "dims": [1000000, 1000000, 1000000],
        "dtype": "uint8"}, "transfer_function": {"preset": "grayscale"}})");
    for (const char* name : {"broken.json", "badtf.json", "short.json", "huge.json", "missing.json"}) {
        const CliRun r = fathom_cli("render " + (d / name).string() + " -o " + out.string(), d);
        EXPECT_EQ(r.status, 1) << name << ": " << r.err;
        EXPECT_NE(r.err.find(name == std::string("short.json") || name == std::string("huge.json")
                                 ? "v_16x12x10_uint8.raw"
                                 : name),
                  std::string::npos)
            << r.err;
        EXPECT_EQ(std::count(r.err.begin(), r.err.end(), '\n'), 1) << r.err;  // one message
        EXPECT_FALSE(fs::exists(out)) << name;
    }
    // an unwritable output leaves nothing behind
    const CliRun w =
        fathom_cli("render " + (d / "scene.json").string() + " -o " + (d / "no/such/dir/x.pfm").string(), d);
    EXPECT_EQ(w.status, 1);
    EXPECT_NE(w.err.find("x.pfm"), std::string::npos);
}

TEST(Cli, InfoDescribesAVolume) {
    TempDir d;
    make_scene(d);
    const std::string cmd = fathom::test::cli() + " info " + (d / "v_16x12x10_uint8.raw").string() + " > " +
                            (d / "info.txt").string();
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    std::ifstream in(d / "info.txt");
    std::stringstream ss;
    ss << in.rdbuf();
    EXPECT_NE(ss.str().find("16"), std::string::npos);
    EXPECT_NE(ss.str().find("uint8"), std::string::npos);
    EXPECT_EQ(fathom_cli("info " + (d / "nothing.nrrd").string(), d).status, 1);
}

TEST(Cli, TfTableWritesPictureAndCsv) {
    TempDir d;
    write(d / "tf.json",
          R"({"format": "fathom-tf/1", "color": [[0, 1, 0.5, 0]], "extinction": [[0, 0], [10, 2]]})");
    const std::string tf = (d / "tf.json").string();
    EXPECT_EQ(fathom_cli("tf-table " + tf + " -o " + (d / "t.png").string() + " --size 16", d).status, 0);
    EXPECT_TRUE(fs::exists(d / "t.png"));
    ASSERT_EQ(
        fathom_cli("tf-table " + tf + " -o " + (d / "t.csv").string() + " --size 3 --range 0,10 --delta 0.5",
                   d)
            .status,
        0);
    std::ifstream in(d / "t.csv");
    std::string header, first, second;
    std::getline(in, header);
    std::getline(in, first);
    std::getline(in, second);
    EXPECT_EQ(header, "v_front,v_back,alpha,r,g,b");
    EXPECT_EQ(first, "0,0,0,0,0,0");  // σ(0) = 0
    // v 5 → 0 over δ 0.5: mean σ = 0.5, α = 1 − e^{−0.25}
    double vf = 0, vb = 0, a = 0;
    char c = 0;
    std::istringstream(second) >> vf >> c >> vb >> c >> a;
    EXPECT_DOUBLE_EQ(vf, 5.0);
    EXPECT_NEAR(a, 1 - std::exp(-0.25), 1e-7);
    EXPECT_EQ(fathom_cli("tf-table " + tf + " -o " + (d / "t.txt").string(), d).status, 2);
    EXPECT_EQ(
        fathom_cli("tf-table " + (d / "none.json").string() + " -o " + (d / "u.png").string(), d).status, 1);
    EXPECT_FALSE(fs::exists(d / "u.png"));
}

TEST(Cli, BenchReportsFrameTimesAsJson) {
    TempDir d;
    make_scene(d);
    const CliRun r = fathom_cli("bench " + (d / "scene.json").string() +
                                    " --frames 3 --width 16 --height 12 --json " + (d / "b.json").string(),
                                d);
    ASSERT_EQ(r.status, 0) << r.err;
    std::ifstream in(d / "b.json");
    const auto j = nlohmann::json::parse(in);
    EXPECT_EQ(j["frames"], 3);
    EXPECT_EQ(j["frame_seconds"].size(), 3u);
    EXPECT_EQ(j["width"], 16);
    EXPECT_EQ(j["integrator"], "preintegrated");
    EXPECT_GT(j["segments_per_second"].get<double>(), 0.0);
    EXPECT_EQ(j["first_seconds"], j["frame_seconds"][0]);
    EXPECT_DOUBLE_EQ(j["first_image_seconds"].get<double>(), j["load_seconds"].get<double>() +
                                                                 j["setup_seconds"].get<double>() +
                                                                 j["first_seconds"].get<double>());
    EXPECT_EQ(j["bricks"], false);       // below RenderSettings::brick_min_bytes
    EXPECT_EQ(j["macrocell_cells"], 0);  // every sample above 0 is visible: no empty macrocell
    // the bundled chest CT under ct-bone: empty macrocells of 2³ cells (a
    // lattice below RenderSettings::fine_macrocells_max)
    const std::string chest = (fathom::test::source_dir() / "data" / "lidc2.nrrd").string();
    ASSERT_EQ(
        fathom_cli("bench --volume " + chest + " --preset ct-bone --frames 1 --width 8 --height 8 --json " +
                       (d / "c.json").string(),
                   d)
            .status,
        0);
    std::ifstream chest_json(d / "c.json");
    EXPECT_EQ(nlohmann::json::parse(chest_json)["macrocell_cells"], 2);
    EXPECT_GT(j["volume_bytes"].get<double>(), 0.0);
    EXPECT_EQ(fathom_cli("bench " + (d / "scene.json").string() + " --frames 1 --no-bricks", d).status, 0);
    EXPECT_EQ(fathom_cli("bench " + (d / "scene.json").string() + " --frames 0", d).status, 2);
    // the summary names the integrator, or the model where it ignores the integrator
    for (const auto& [flags, name] : {std::pair<std::string, std::string>{"", " preintegrated step"},
                                      {" --model mip", " mip step"},
                                      {" --iso 100", " isosurface step"}}) {
        const auto run =
            fathom::test::run_cli("bench " + (d / "scene.json").string() + " --frames 1" + flags, d);
        ASSERT_EQ(run.status, 0) << run.err;
        EXPECT_NE(run.out.find(name), std::string::npos) << run.out;
    }
}

TEST(Cli, ClipPlaneAndCropFlags) {
    TempDir d;
    make_scene(d, R"(, "background": [0.25, 0.25, 0.25])");
    const std::string scene = (d / "scene.json").string();
    ASSERT_EQ(fathom_cli("render " + scene + " -o " + (d / "full.pfm").string(), d).status, 0);
    // A plane that keeps nothing of the volume (x ≥ 100): every pixel is the background.
    CliRun r =
        fathom_cli("render " + scene + " --clip-plane 100,0,0,1,0,0 -o " + (d / "none.pfm").string(), d);
    ASSERT_EQ(r.status, 0) << r.err;
    const fathom::Image none = fathom::read_pfm(d / "none.pfm"), full = fathom::read_pfm(d / "full.pfm");
    for (int y = 0; y < none.height; ++y)
        for (int x = 0; x < none.width; ++x) EXPECT_FLOAT_EQ(none.pixel(x, y)[0], 0.25f);
    // A crop box holding the whole volume changes nothing.
    r = fathom_cli("render " + scene + " --crop -1,-1,-1,100,100,100 -o " + (d / "crop.pfm").string(), d);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_EQ(fathom::read_pfm(d / "crop.pfm").rgba, full.rgba);
    EXPECT_EQ(fathom_cli("render " + scene + " --clip-plane 1,2,3 -o x.pfm", d).status, 2);
    r = fathom_cli("render " + scene + " --clip-plane 0,0,0,0,0,0 -o " + (d / "bad.pfm").string(), d);
    EXPECT_EQ(r.status, 2);  // a bad flag value is a usage error
    EXPECT_NE(r.err.find("clipping plane"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(d / "bad.pfm"));
}

TEST(Cli, ShadeAndPhongFlags) {
    TempDir d;
    make_scene(d);
    const std::string scene = (d / "scene.json").string();
    ASSERT_EQ(fathom_cli("render " + scene + " -o " + (d / "flat.pfm").string(), d).status, 0);
    CliRun r = fathom_cli("render " + scene + " --shade -o " + (d / "lit.pfm").string(), d);
    ASSERT_EQ(r.status, 0) << r.err;
    r = fathom_cli("render " + scene + " --phong 0.1,0.7,0.2,10 -o " + (d / "phong.pfm").string(), d);
    ASSERT_EQ(r.status, 0) << r.err;
    const auto flat = fathom::read_pfm(d / "flat.pfm").rgba, lit = fathom::read_pfm(d / "lit.pfm").rgba;
    EXPECT_NE(flat, lit);
    EXPECT_EQ(lit, fathom::read_pfm(d / "phong.pfm").rgba);  // --phong with the defaults = --shade
    EXPECT_EQ(fathom_cli("render " + scene + " --phong 1,2 -o x.pfm", d).status, 2);
    EXPECT_EQ(fathom_cli("render " + scene + " --phong 0.1,0.7,-1,10 -o x.pfm", d).status, 2);
}

TEST(Cli, IsoFlagSelectsTheIsosurfaceModel) {
    TempDir d;
    make_scene(d);
    const std::string scene = (d / "scene.json").string();
    CliRun r = fathom_cli("render " + scene + " --iso 100,1,0.9,0.8 -o " + (d / "iso.pfm").string(), d);
    ASSERT_EQ(r.status, 0) << r.err;
    const fathom::Image img = fathom::read_pfm(d / "iso.pfm");
    int opaque = 0;
    for (int y = 0; y < img.height; ++y)
        for (int x = 0; x < img.width; ++x) opaque += img.pixel(x, y)[3] == 1.0f;
    EXPECT_GT(opaque, 10);
    EXPECT_EQ(fathom_cli("render " + scene + " --iso 1,2 -o x.pfm", d).status, 2);
    EXPECT_EQ(fathom_cli("render " + scene + " --model isosurface -o x.pfm", d).status, 2);
}

TEST(Cli, OrbitFramesWriteATurntableAndItsTransforms) {
    TempDir d;
    make_scene(d);
    const std::string scene = (d / "scene.json").string();
    const CliRun r = fathom_cli("render " + scene + " --orbit-frames 3 --transforms " +
                                    (d / "transforms.json").string() + " -o " + (d / "f.pfm").string(),
                                d);
    ASSERT_EQ(r.status, 0) << r.err;
    std::ifstream in(d / "transforms.json");
    const auto j = nlohmann::json::parse(in);
    ASSERT_EQ(j["frames"].size(), 3u);
    const fathom::Scene sc = fathom::load_scene(d / "scene.json");
    // camera_angle_x is the horizontal field of view of SPEC §9
    const double ax = j["camera_angle_x"].get<double>();
    const double fov_y = 2 * std::atan(std::tan(ax / 2) * sc.settings.height / sc.settings.width);
    EXPECT_NEAR(fov_y * 180 / std::numbers::pi, sc.camera.fov_y_deg, 1e-9);
    for (int f = 0; f < 3; ++f) {
        const auto& fr = j["frames"][static_cast<std::size_t>(f)];
        EXPECT_EQ(fr["file_path"], "f_00" + std::to_string(f) + ".pfm");
        std::array<double, 16> m{};
        for (int row = 0; row < 4; ++row)
            for (int c = 0; c < 4; ++c)
                m[static_cast<std::size_t>(4 * row + c)] =
                    fr["transform_matrix"][static_cast<std::size_t>(row)][static_cast<std::size_t>(c)];
        fathom::Camera cam = fathom::Camera::from_matrix(m);
        cam.fov_y_deg = fov_y * 180 / std::numbers::pi;
        // The frame on disk is what the library renders from the written camera.
        const fathom::Image want = sc.renderer().render(cam);
        const fathom::Image got = fathom::read_pfm(d / ("f_00" + std::to_string(f) + ".pfm"));
        ASSERT_EQ(got.rgba.size(), want.rgba.size());
        for (std::size_t i = 0; i < got.rgba.size(); ++i)  // PFM holds RGB only
            if (i % 4 != 3) {
                ASSERT_NEAR(got.rgba[i], want.rgba[i], 1e-5) << f << " " << i;
            }
    }
    // frames differ (the camera turned)
    EXPECT_NE(fathom::read_pfm(d / "f_000.pfm").rgba, fathom::read_pfm(d / "f_001.pfm").rgba);
    EXPECT_EQ(fathom_cli("render " + scene + " --transforms t.json -o x.png", d).status, 2);
    EXPECT_EQ(fathom_cli("render " + scene + " --orbit-frames -2 -o x.png", d).status, 2);
    EXPECT_EQ(fathom_cli("render " + scene + " --video v.mp4 -o x.png", d).status, 2);
    EXPECT_EQ(fathom_cli("render " + scene + " --orbit-frames 2 --video v.avi -o x.png", d).status, 2);
    if (fathom::video_supported()) {
        const CliRun v = fathom_cli("render " + scene + " --orbit-frames 3 --video " +
                                        (d / "v.gif").string() + " -o " + (d / "g.png").string(),
                                    d);
        ASSERT_EQ(v.status, 0) << v.err;
        EXPECT_GT(fs::file_size(d / "v.gif"), 100u);
        EXPECT_TRUE(fs::exists(d / "g_002.png"));
    }
}

TEST(Cli, DepthOutputs) {
    TempDir d;
    make_scene(d);
    const std::string scene = (d / "scene.json").string();
    const CliRun r =
        fathom_cli("render " + scene + " -o " + (d / "c.png").string() + " --depth-out " +
                       (d / "depth.pfm").string() + " --first-hit-out " + (d / "hit.exr").string(),
                   d);
    ASSERT_EQ(r.status, 0) << r.err;
    const fathom::Image depth = fathom::read_pfm(d / "depth.pfm");
    const fathom::Image hit = fathom::read_exr(d / "hit.exr");
    int finite = 0, misses = 0;
    for (int y = 0; y < depth.height; ++y)
        for (int x = 0; x < depth.width; ++x) {
            const float dz = depth.pixel(x, y)[0], h = hit.pixel(x, y)[0];
            if (std::isfinite(dz)) {
                ++finite;
                EXPECT_LE(h, dz + 1e-3f);
            } else {
                ++misses;
            }
        }
    EXPECT_GT(finite, 100);
    EXPECT_GT(misses, 0);
    EXPECT_EQ(fathom_cli("render " + scene + " -o x.png --depth-out d.png", d).status, 2);
    // --depth-channels: the same depths inside the EXR image.
    const CliRun e = fathom_cli("render " + scene + " -o " + (d / "c.exr").string() + " --depth-channels", d);
    ASSERT_EQ(e.status, 0) << e.err;
    const fathom::Image c = fathom::read_exr(d / "c.exr");
    ASSERT_EQ(c.depth.size(), static_cast<std::size_t>(depth.width * depth.height));
    for (int y = 0; y < depth.height; y += 7)
        for (int x = 0; x < depth.width; x += 7) {
            const float a = depth.pixel(x, y)[0], b = c.depth[static_cast<std::size_t>(y * depth.width + x)];
            EXPECT_TRUE(a == b || (std::isinf(a) && std::isinf(b))) << x << "," << y;
        }
    EXPECT_EQ(fathom_cli("render " + scene + " -o x.png --depth-channels", d).status, 2);
}
