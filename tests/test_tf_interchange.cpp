// Transfer-function interchange: 3D Slicer presets (XML), ParaView colormap
// JSON, the embedded Slicer presets, TransferFunction::from_file's content
// detection and `fathom tf-convert`.
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"
#include "fathom/tf_interchange.h"
#include "fathom/transfer_function.h"

#include "test_util.h"

using namespace fathom;
using fathom::test::expect_error;
using fathom::test::TempDir;
namespace fs = std::filesystem;

namespace {

void write(const fs::path& p, const std::string& text) {
    std::ofstream(p, std::ios::binary) << text;
}


class WarningCatcher {
public:
    WarningCatcher() : previous_(set_warning_sink([this](const std::string& m) { messages.push_back(m); })) {}
    ~WarningCatcher() { set_warning_sink(previous_); }
    WarningCatcher(const WarningCatcher&) = delete;
    WarningCatcher& operator=(const WarningCatcher&) = delete;
    [[nodiscard]] bool any_contains(const std::string& word) const {
        for (const auto& m : messages)
            if (m.find(word) != std::string::npos) return true;
        return false;
    }
    std::vector<std::string> messages;

private:
    WarningSink previous_;
};

// Every field equal; colours within `color_tol` (sRGB round trips), the rest exact.
void expect_same(const TransferFunction& a, const TransferFunction& b, double color_tol = 0.0) {
    EXPECT_EQ(a.name, b.name);
    EXPECT_EQ(a.alpha_kind, b.alpha_kind);
    EXPECT_EQ(a.alpha_points, b.alpha_points) << a.name;
    EXPECT_EQ(a.opacity_unit_distance, b.opacity_unit_distance) << a.name;
    EXPECT_EQ(a.associated, b.associated);
    EXPECT_EQ(a.gradient_opacity_points, b.gradient_opacity_points) << a.name;
    ASSERT_EQ(a.color_points.size(), b.color_points.size()) << a.name;
    for (std::size_t k = 0; k < a.color_points.size(); ++k) {
        EXPECT_EQ(a.color_points[k].first, b.color_points[k].first) << a.name << " point " << k;
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(a.color_points[k].second[c], b.color_points[k].second[c], color_tol)
                << a.name << " point " << k;
    }
}

// Two presets in Slicer's own layout; the second with a real gradient opacity.
const char* const kSample = R"(<?xml version="1.0" encoding="utf-8"?>
<MRML>
  <VolumeProperty name="Sample-Bone" gradientOpacity="4 0 1 255 1" specularPower="10"
    scalarOpacity="8 -3024 0 -16.4458 0 641.385 0.715686 3071 0.705882" shade="1"
    colorTransfer="16 -3024 0 0 0 -16.4458 0.729412 0.254902 0.301961 641.385 0.905882 0.815686 0.552941 3071 1 1 1"
    interpolation="1"/>
  <VolumeProperty name="Sample-Edges" gradientOpacity="6 0 0 20 0.5 100 1"
    scalarOpacity="4 0 0 100 1" colorTransfer="8 0 0.5 0.5 0.5 100 1 1 1"/>
</MRML>
)";

std::vector<std::pair<double, double>> pairs(std::initializer_list<double> xs) {
    std::vector<std::pair<double, double>> out;
    for (auto it = xs.begin(); it != xs.end(); it += 2) out.push_back({*it, *(it + 1)});
    return out;
}

fs::path slicer_xml() {
    return fathom::test::source_dir() / "presets" / "slicer" / "presets.xml";
}

using fathom::test::CliRun;
using fathom::test::run_cli;

}  // namespace

// ------------------------------------------------------------------ Slicer

TEST(TfInterchange, SlicerSampleParses) {
    const auto all = slicer_presets_from_text(kSample, "sample.xml");
    ASSERT_EQ(all.size(), 2u);
    const TransferFunction& bone = all[0];
    EXPECT_EQ(bone.name, "Sample-Bone");
    EXPECT_EQ(bone.alpha_kind, TransferFunction::Alpha::opacity);
    EXPECT_EQ(bone.alpha_points, pairs({-3024, 0, -16.4458, 0, 641.385, 0.715686, 3071, 0.705882}));
    ASSERT_TRUE(bone.opacity_unit_distance.has_value());
    EXPECT_EQ(*bone.opacity_unit_distance, 1.0);  // VTK's default: opacity per world unit (mm)
    EXPECT_FALSE(bone.associated);
    ASSERT_EQ(bone.color_points.size(), 4u);
    EXPECT_EQ(bone.color_points[1].first, -16.4458);
    // VTK's display colours are sRGB-decoded to fathom's linear colours
    EXPECT_DOUBLE_EQ(bone.color_points[1].second[0], std::pow((0.729412 + 0.055) / 1.055, 2.4));
    EXPECT_DOUBLE_EQ(bone.color_points[3].second[2], 1.0);
    EXPECT_DOUBLE_EQ(bone.color_points[0].second[1], 0.0);
    EXPECT_TRUE(bone.gradient_opacity_points.empty());  // constant 1: no modulation

    const TransferFunction& edges = all[1];
    EXPECT_EQ(edges.gradient_opacity_points, pairs({0, 0, 20, 0.5, 100, 1}));
    EXPECT_NEAR(edges.color_points[0].second[1], 0.21404114048223255, 1e-15);  // sRGB 0.5

    // the result is a valid fathom-tf/1 transfer function
    expect_same(TransferFunction::from_json_text(edges.to_json(), "x.json"), edges);
}

TEST(TfInterchange, SlicerPresetByName) {
    TempDir d;
    write(d / "presets.xml", kSample);
    EXPECT_EQ(read_slicer_preset(d / "presets.xml", "Sample-Edges").name, "Sample-Edges");
    EXPECT_EQ(read_slicer_presets(d / "presets.xml").size(), 2u);
    expect_error([&] { read_slicer_preset(d / "presets.xml", "sample-edges"); }, d / "presets.xml",
                 {"no preset named 'sample-edges'", "'Sample-Bone'", "'Sample-Edges'"});
}

TEST(TfInterchange, SlicerErrorsNameTheFileAndThePreset) {
    TempDir d;
    const fs::path f = d / "bad.xml";
    auto check = [&](const std::string& xml, const std::vector<std::string>& words) {
        write(f, xml);
        expect_error([&] { read_slicer_presets(f); }, f, words);
        expect_error([&] { TransferFunction::from_file(f); }, f, words);
    };
    auto prop = [](const std::string& opacity, const std::string& color, const std::string& extra = "") {
        return "<MRML><VolumeProperty name=\"P\" scalarOpacity=\"" + opacity + "\" colorTransfer=\"" + color +
               "\" " + extra + "/></MRML>";
    };
    const std::string ok_o = "4 0 0 10 1", ok_c = "8 0 0 0 0 10 1 1 1";
    check("<MRML><VolumeProperty name=\"P\" scalarOpacity=\"4 0 0 10 1\"</MRML>", {"invalid XML"});
    check("<MRML><Other/></MRML>", {"no <VolumeProperty>"});
    check(prop("6 0 0 10 1", ok_c), {"preset 'P'", "scalarOpacity", "count says 6", "4 follow"});
    check(prop("3 0 0 10", ok_c), {"scalarOpacity", "3 numbers", "2-number points"});
    check(prop(ok_o, "7 0 0 0 0 10 1 1"), {"colorTransfer", "4-number points"});
    check(prop("4 10 0 0 1", ok_c), {"scalarOpacity", "not sorted"});
    check(prop("4 0 nan 10 1", ok_c), {"scalarOpacity", "'nan' is not finite"});
    check(prop("4 0 0 10 1.5", ok_c), {"opacity 1.5", "outside [0, 1]"});
    check(prop("4 0 0 10 x", ok_c), {"'x' is not a number"});
    check(prop(ok_o, "8 0 0 0 0 10 1 2 1"), {"colorTransfer", "outside [0, 1]"});
    check(prop(ok_o, ok_c, "gradientOpacity=\"4 -1 1 10 1\""), {"gradientOpacity", "negative"});
    check(prop("", ok_c), {"scalarOpacity", "empty"});
    check(prop("0", ok_c), {"scalarOpacity", "no points"});
    check("<MRML><VolumeProperty name=\"P\" scalarOpacity=\"4 0 0 1 1\"/></MRML>", {"no 'colorTransfer'"});
}

// ------------------------------------------------------------------ embedded presets

TEST(TfInterchange, EveryEmbeddedSlicerPresetMatchesSlicersXml) {
    ASSERT_TRUE(fs::exists(slicer_xml())) << slicer_xml();
    const auto xml = read_slicer_presets(slicer_xml());
    EXPECT_EQ(xml.size(), 25u);
    const auto names = TransferFunction::preset_names();
    for (const auto& want : xml) {
        EXPECT_NE(std::find(names.begin(), names.end(), want.name), names.end()) << want.name;
        // absolute units: the value range of the volume does not move the points
        const auto a = TransferFunction::preset(want.name, {0.0, 255.0});
        const auto b = TransferFunction::preset(want.name, {-1024.0, 3071.0});
        expect_same(a, want);
        expect_same(b, want);
    }
    // fathom's 5 own presets, then Slicer's
    EXPECT_EQ(names.size(), 5u + xml.size());
}

TEST(TfInterchange, CtBoneHasSlicersNumbers) {
    const auto tf = TransferFunction::preset("CT-Bone", {0.0, 1.0});
    EXPECT_EQ(tf.name, "CT-Bone");
    EXPECT_EQ(tf.alpha_points, pairs({-3024, 0, -16.4458, 0, 641.385, 0.715686, 3071, 0.705882}));
    EXPECT_EQ(tf.opacity_unit_distance, 1.0);
    ASSERT_EQ(tf.color_points.size(), 4u);
    const double xml[4][4] = {{-3024, 0, 0, 0},
                              {-16.4458, 0.729412, 0.254902, 0.301961},
                              {641.385, 0.905882, 0.815686, 0.552941},
                              {3071, 1, 1, 1}};
    for (int k = 0; k < 4; ++k) {
        EXPECT_EQ(tf.color_points[k].first, xml[k][0]);
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(linear_to_srgb(tf.color_points[k].second[c]), xml[k][1 + c], 1e-12);
    }
    // at 641.385 HU, σ = −ln(1 − 0.715686) per mm
    const Classifier cl(tf, 0.5);
    EXPECT_NEAR(cl.sigma(641.385), -std::log(1 - 0.715686), 1e-12);
    EXPECT_EQ(cl.sigma(-100), 0.0);
}

TEST(TfInterchange, EveryPresetRoundTripsThroughFathomJson) {
    for (const auto& name : TransferFunction::preset_names()) {
        const auto tf = TransferFunction::preset(name, {-1024.0, 3071.0});
        expect_same(TransferFunction::from_json_text(tf.to_json(), name + ".json"), tf);
    }
}

TEST(TfInterchange, PresetNamesAreCaseSensitiveWithAHint) {
    // fathom's ct-bone (normalised) and Slicer's CT-Bone (Hounsfield) are different presets
    const auto mine = TransferFunction::preset("ct-bone", {0.0, 255.0});
    EXPECT_EQ(mine.alpha_points.back().first, 255.0);
    EXPECT_FALSE(mine.opacity_unit_distance.has_value());
    expect_error(
        [] {
            TransferFunction::preset("ct-bones", {0.0, 1.0});
        },
        "preset 'ct-bones'", {"unknown preset", "did you mean 'CT-Bones'", "CT-AAA", "ct-skin"});
}

// ------------------------------------------------------------------ ParaView

TEST(TfInterchange, ParaViewExportImportRoundTrip) {
    TransferFunction tf;
    tf.name = "round \"trip\"";
    tf.alpha_points = pairs({-1000, 0, 0.125, 0.25, 400.5, 0.75, 3000, 1});
    tf.color_points = {{-1000, {0, 0, 0}}, {10, {0.2, 0.01, 0.001}}, {3000, {1, 0.5, 0.25}}};
    const std::string text = to_paraview_json(tf);
    const auto j = nlohmann::json::parse(text);
    ASSERT_TRUE(j.is_array());
    ASSERT_EQ(j.size(), 1u);
    EXPECT_EQ(j[0]["Name"], tf.name);
    EXPECT_EQ(j[0]["ColorSpace"], "RGB");
    EXPECT_EQ(j[0]["RGBPoints"].size(), 12u);
    EXPECT_EQ(j[0]["Points"].size(), 16u);
    EXPECT_EQ(j[0]["Points"][2], 0.5);                                            // midpoint
    EXPECT_EQ(j[0]["Points"][3], 0.0);                                            // sharpness
    EXPECT_EQ(j[0]["RGBPoints"][9], 1.0);                                         // 1 stays exactly 1
    EXPECT_NEAR(j[0]["RGBPoints"][10].get<double>(), 0.7353569830524495, 1e-12);  // linear 0.5 → sRGB

    WarningCatcher w;
    const auto back = paraview_colormap_from_text(text, "rt.json");
    expect_same(back, tf, 1e-12);
    EXPECT_TRUE(w.messages.empty()) << w.messages.front();
    // and once more through the file reader and from_file's detection
    TempDir d;
    write(d / "rt.json", text);
    expect_same(read_paraview_colormap(d / "rt.json"), tf, 1e-12);
    expect_same(TransferFunction::from_file(d / "rt.json"), tf, 1e-12);
}

TEST(TfInterchange, ParaViewExportOfJumpsAndExtinction) {
    TransferFunction tf;
    tf.alpha_kind = TransferFunction::Alpha::extinction;
    tf.alpha_points = pairs({0, 0, 10, 0, 10, 2, 20, 2});
    tf.color_points = {{0, {1, 1, 1}}, {20, {2, 1, 1}}};
    WarningCatcher w;
    const auto back = paraview_colormap_from_text(to_paraview_json(tf), "x.json");
    EXPECT_TRUE(w.any_contains("Unit Distance to 1"));
    EXPECT_TRUE(w.any_contains("clamped to 1"));
    ASSERT_EQ(back.alpha_points.size(), 4u);
    EXPECT_EQ(back.name, "fathom");
    // the jump moves by one representable step (VTK holds one point per value)
    EXPECT_EQ(back.alpha_points[1].first, 10.0);
    EXPECT_EQ(back.alpha_points[2].first, std::nextafter(10.0, 11.0));
    EXPECT_NEAR(back.alpha_points[2].second, 1 - std::exp(-2.0), 1e-15);  // σ per world unit → opacity
    EXPECT_NEAR(back.color_points[1].second[0], 1.0, 1e-12);

    TransferFunction em = tf;
    em.associated = true;
    em.name = "glow";
    expect_error([&] { (void)to_paraview_json(em); }, "transfer function 'glow'", {"emission", "ParaView"});
}

TEST(TfInterchange, ParaViewImportChoicesAndWarnings) {
    const std::string text = R"([
      {"Name": "Ramp", "ColorSpace": "RGB", "RGBPoints": [-1, 0, 0, 0, 1, 1, 1, 1], "NanColor": [1, 1, 0]},
      {"Name": "Curvy", "ColorSpace": "Diverging", "Creator": "Someone",
       "RGBPoints": [0, 0.23, 0.299, 0.754, 0.5, 0.865, 0.865, 0.865, 1, 0.706, 0.016, 0.15],
       "Points": [0, 0, 0.3, 0, 0.5, 0.4, 0.5, 0.2, 1, 1, 0.9, 0.9]},
      {"Name": "Steps", "ColorSpace": "Step", "RGBPoints": [0, 1, 0, 0, 5, 0, 1, 0, 10, 0, 0, 1]},
      {"Name": "Cats", "IndexedColors": [1, 0, 0, 0, 1, 0], "Annotations": ["a", "A", "b", "B"]}
    ])";
    {
        WarningCatcher w;
        const auto ramp = paraview_colormap_from_text(text, "maps.json");  // the first
        EXPECT_EQ(ramp.name, "Ramp");
        EXPECT_EQ(ramp.alpha_points, pairs({-1, 0, 1, 1}));  // ParaView's default opacity: a ramp
        EXPECT_FALSE(ramp.opacity_unit_distance.has_value());
        EXPECT_TRUE(w.messages.empty());
    }
    {
        WarningCatcher w;
        const auto curvy = paraview_colormap_from_text(text, "maps.json", "Curvy");
        EXPECT_EQ(curvy.alpha_points, pairs({0, 0, 0.5, 0.4, 1, 1}));
        EXPECT_TRUE(w.any_contains("colour space 'Diverging'"));
        // two segments are shaped (the last point's midpoint shapes nothing)
        EXPECT_TRUE(w.any_contains("2 opacity segment(s)"));
    }
    {
        const auto steps = paraview_colormap_from_text(text, "maps.json", "Steps");
        ASSERT_EQ(steps.color_points.size(), 5u);  // jumps at 5 and 10
        const Classifier c(steps, 1.0);
        EXPECT_EQ(c.color(4.9)[0], 1.0);
        EXPECT_EQ(c.color(5.0)[1], 1.0);
        EXPECT_EQ(c.color(9.99)[1], 1.0);
        EXPECT_EQ(c.color(10.0)[2], 1.0);
    }
    expect_error([&] { paraview_colormap_from_text(text, "maps.json", "Cats"); }, "maps.json",
                 {"colormap 'Cats'", "indexed"});
    expect_error([&] { paraview_colormap_from_text(text, "maps.json", "Nope"); }, "maps.json",
                 {"no colormap named 'Nope'", "'Ramp'", "'Steps'"});
    // a single object (not a list) is one colormap
    EXPECT_EQ(paraview_colormap_from_text(R"({"Name": "One", "RGBPoints": [0, 1, 1, 1]})", "one.json").name,
              "One");
}

TEST(TfInterchange, ParaViewErrorsNameTheFile) {
    TempDir d;
    const fs::path f = d / "cm.json";
    auto check = [&](const std::string& text, const std::vector<std::string>& words) {
        write(f, text);
        expect_error([&] { read_paraview_colormap(f); }, f, words);
        expect_error([&] { TransferFunction::from_file(f); }, f, words);
    };
    check(R"([{"Name": "A", "RGBPoints": [0, 1, 1]}])", {"colormap 'A'", "RGBPoints", "4-number points"});
    check(R"([{"Name": "A", "RGBPoints": [1, 1, 1, 1, 0, 0, 0, 0]}])", {"RGBPoints", "not sorted"});
    check(R"([{"Name": "A", "RGBPoints": [0, 1, 1, 1], "Points": [0, 2, 0.5, 0]}])",
          {"Points", "opacity 2", "outside [0, 1]"});
    check(R"([{"Name": "A", "RGBPoints": [0, 1, 1, "x"]}])", {"expected a number"});
    check(R"([{"Name": "A", "RGBPoints": [0, 1, 1, NaN]}])", {"invalid JSON"});
    check(R"([{"Name": "A", "RGBPoints": [0, 1, 1, 1e999]}])", {"invalid JSON", "overflow"});
    check(R"([{"Name": "A"}])", {"no 'RGBPoints'"});
    check(R"([])", {"empty list"});
    check(R"([3])", {"entry 0 is not an object"});
    check(R"([{"Name": "A", "RGBPoints": [0, 1, 1, 1])", {"invalid JSON"});
}

// ------------------------------------------------------------------ detection

TEST(TfInterchange, FromFileDetectsTheFormatByContent) {
    EXPECT_EQ(detect_tf_format("\xEF\xBB\xBF  <?xml version=\"1.0\"?><MRML/>"), TfFileFormat::slicer);
    EXPECT_EQ(detect_tf_format(" [ {} ]"), TfFileFormat::paraview);
    EXPECT_EQ(detect_tf_format(R"({"RGBPoints": [0, 1, 1, 1]})"), TfFileFormat::paraview);
    EXPECT_EQ(detect_tf_format(R"({"format": "fathom-tf/1"})"), TfFileFormat::fathom);
    EXPECT_EQ(detect_tf_format("{ broken"), TfFileFormat::fathom);

    TempDir d;
    // a Slicer file under a .json name: the content decides
    write(d / "slicer.json", kSample);
    WarningCatcher w;
    const auto first = TransferFunction::from_file(d / "slicer.json");
    EXPECT_EQ(first.name, "Sample-Bone");
    EXPECT_TRUE(w.any_contains("holds 2 presets; using the first, 'Sample-Bone'"));
    EXPECT_EQ(read_transfer_function(d / "slicer.json", "Sample-Edges").name, "Sample-Edges");
    // fathom-tf/1 still reads as before, and its errors are unchanged
    const auto tf = TransferFunction::preset("CT-Bone", {0, 1});
    write(d / "bone.json", tf.to_json());
    expect_same(TransferFunction::from_file(d / "bone.json"), tf);
    expect_error([&] { read_transfer_function(d / "bone.json", "Other"); }, d / "bone.json",
                 {"fathom-tf/1 file holds one transfer function"});
    write(d / "bad.json", R"({"format": "fathom-tf/1", "colour": []})");
    expect_error([&] { TransferFunction::from_file(d / "bad.json"); }, d / "bad.json",
                 {"unknown key 'colour'"});
    expect_error([&] { TransferFunction::from_file(d / "missing.xml"); }, d / "missing.xml",
                 {"does not exist"});
    expect_error([&] { TransferFunction::from_file(d.path()); }, d.path(), {"not a regular file"});
}

TEST(TfInterchange, SrgbRoundTrips) {
    for (double x : {0.0, 0.001, 0.0031308, 0.04045, 0.2, 0.5, 0.9, 1.0, 2.0}) {
        EXPECT_NEAR(srgb_to_linear(linear_to_srgb(x)), x, 1e-14 * std::max(1.0, x));
        EXPECT_NEAR(linear_to_srgb(srgb_to_linear(x)), x, 1e-14 * std::max(1.0, x));
    }
    EXPECT_NEAR(linear_to_srgb(0.5), 0.7353569830524495, 1e-15);
}

// ------------------------------------------------------------------ CLI

TEST(TfInterchange, CliConvertsSlicerAndParaView) {
    TempDir d;
    const std::string xml = slicer_xml().string();
    // a Slicer preset out of presets.xml, as fathom-tf/1
    CliRun r = run_cli("tf-convert " + xml + " " + (d / "bone.json").string() + " --name CT-Bone", d);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.out.find("CT-Bone"), std::string::npos);
    expect_same(TransferFunction::from_file(d / "bone.json"), TransferFunction::preset("CT-Bone", {0, 1}));
    // a preset name to ParaView, and back to fathom
    r = run_cli("tf-convert CT-Lung " + (d / "lung_pv.json").string() + " --to paraview", d);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.err.find("Scalar Opacity Unit Distance to 1"), std::string::npos) << r.err;
    r = run_cli("tf-convert " + (d / "lung_pv.json").string() + " " + (d / "lung.json").string(), d);
    ASSERT_EQ(r.status, 0) << r.err;
    auto lung = TransferFunction::from_file(d / "lung.json");
    auto want = TransferFunction::preset("CT-Lung", {0, 1});
    want.opacity_unit_distance.reset();  // a ParaView colormap has none
    expect_same(lung, want, 1e-12);
    // fathom's normalised presets follow --range
    r = run_cli("tf-convert ct-bone " + (d / "ct.json").string() + " --range 0,4095", d);
    ASSERT_EQ(r.status, 0) << r.err;
    expect_same(TransferFunction::from_file(d / "ct.json"), TransferFunction::preset("ct-bone", {0, 4095}));
}

TEST(TfInterchange, CliErrorsAndUsage) {
    TempDir d;
    const std::string out = (d / "out.json").string();
    // bad input: exit 1, one message naming the file, no output
    write(d / "broken.xml", "<MRML><VolumeProperty name='x'");
    CliRun r = run_cli("tf-convert " + (d / "broken.xml").string() + " " + out, d);
    EXPECT_EQ(r.status, 1);
    EXPECT_NE(r.err.find((d / "broken.xml").string()), std::string::npos) << r.err;
    EXPECT_NE(r.err.find("invalid XML"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
    r = run_cli("tf-convert " + (d / "nothing.xml").string() + " " + out, d);
    EXPECT_EQ(r.status, 1);
    EXPECT_NE(r.err.find("not a preset name"), std::string::npos) << r.err;
    r = run_cli("tf-convert " + slicer_xml().string() + " " + out + " --name CT-Nope", d);
    EXPECT_EQ(r.status, 1);
    EXPECT_NE(r.err.find("no preset named 'CT-Nope'"), std::string::npos) << r.err;
    EXPECT_FALSE(fs::exists(out));
    // usage errors: exit 2
    EXPECT_EQ(run_cli("tf-convert CT-Bone " + (d / "out.txt").string(), d).status, 2);
    EXPECT_EQ(run_cli("tf-convert CT-Bone " + out + " --to slicer", d).status, 2);
    EXPECT_EQ(run_cli("tf-convert CT-Bone", d).status, 2);
    EXPECT_EQ(run_cli("tf-convert ct-bone " + out + " --range 5,1", d).status, 2);
    EXPECT_FALSE(fs::exists(out));
}

TEST(TfInterchange, RenderTakesASlicerFileAsTf) {
    TempDir d;
    {
        std::ofstream v(d / "v_16x12x10_int16.raw", std::ios::binary);
        for (int k = 0; k < 10; ++k)
            for (int j = 0; j < 12; ++j)
                for (int i = 0; i < 16; ++i) {
                    const auto s = static_cast<std::int16_t>(-1000 + 150 * i + 40 * j);
                    v.write(reinterpret_cast<const char*>(&s), sizeof s);
                }
    }
    const std::string base = "render --volume " + (d / "v_16x12x10_int16.raw").string() +
                             " --orbit 30,20 --width 24 --height 16 -o ";
    CliRun r = run_cli(base + (d / "a.pfm").string() + " --tf " + slicer_xml().string(), d);
    ASSERT_EQ(r.status, 0) << r.err;
    EXPECT_NE(r.err.find("using the first, 'CT-AAA'"), std::string::npos) << r.err;
    r = run_cli(base + (d / "b.pfm").string() + " --preset CT-AAA", d);
    ASSERT_EQ(r.status, 0) << r.err;
    const Image a = read_pfm(d / "a.pfm"), b = read_pfm(d / "b.pfm");
    ASSERT_EQ(a.width, 24);
    EXPECT_EQ(a.rgba, b.rgba);  // the file's first preset is the embedded CT-AAA
    double sum = 0;
    for (float x : a.rgba) sum += x;
    EXPECT_GT(sum, 0.0);  // something is visible
}
