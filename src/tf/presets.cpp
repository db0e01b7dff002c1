// Built-in transfer-function presets. fathom's own (lower-case names) are
// written over the normalised scalar range [0, 1] and scaled to the value
// range of the volume they are applied to (as ParaView rescales a colormap to
// the data range), so one preset serves a uint8 CT, a 12-bit CT and a float
// field alike. The positions were chosen by looking at the histograms and
// renders of the CT and MR scans fathom is tested on (docs/presets.md).
//
// 3D Slicer's volume-rendering presets (CT-Bone, MR-Default, ...) are in
// absolute scalar units (Hounsfield for CT) and are never rescaled. Their
// fathom-tf/1 files, presets/slicer/*.json (converted from Slicer's
// presets.xml: presets/slicer/NOTICE.md), are compiled into the library by
// CMakeLists.txt, so the binary does not need the source tree.
#include <algorithm>

#include "fathom/error.h"
#include "fathom/transfer_function.h"

#include "io/io_util.h"

namespace fathom {
namespace embedded {
// Generated from presets/slicer/*.json: {name, fathom-tf/1 JSON text},
// sorted by name, ending with {nullptr, nullptr}.
extern const char* const kSlicerPresets[][2];
}  // namespace embedded

namespace {

struct PresetDef {
    const char* name;
    std::vector<std::pair<double, Rgb>> color;
    std::vector<std::pair<double, double>> opacity;  // opacity per voxel (unit distance = smallest spacing)
};

const std::vector<PresetDef>& presets() {
    static const std::vector<PresetDef> kPresets = {
        // Bone: nothing below 45 % of the range, then a steep ramp to opaque
        // ivory (LIDC2 ribs and spine, CThead skull).
        {"ct-bone",
         {{0.0, {0.0, 0.0, 0.0}},
          {0.45, {0.6, 0.35, 0.25}},
          {0.6, {0.95, 0.9, 0.8}},
          {1.0, {1.0, 1.0, 0.97}}},
         {{0.0, 0.0}, {0.45, 0.0}, {0.6, 0.6}, {1.0, 0.9}}},
        // Skin: a faint, translucent skin-coloured band over soft tissue and a
        // denser white for bone.
        {"ct-skin",
         {{0.0, {0.0, 0.0, 0.0}},
          {0.05, {0.85, 0.55, 0.45}},
          {0.45, {0.95, 0.75, 0.65}},
          {0.6, {1.0, 0.95, 0.88}},
          {1.0, {1.0, 1.0, 1.0}}},
         {{0.0, 0.0}, {0.04, 0.0}, {0.07, 0.012}, {0.45, 0.012}, {0.6, 0.25}, {1.0, 0.5}}},
        // Soft tissue: muscle/organ reds at low opacity, bone white.
        {"ct-soft-tissue",
         {{0.0, {0.0, 0.0, 0.0}},
          {0.05, {0.7, 0.25, 0.2}},
          {0.4, {0.9, 0.45, 0.35}},
          {0.55, {1.0, 0.9, 0.8}},
          {1.0, {1.0, 1.0, 1.0}}},
         {{0.0, 0.0}, {0.05, 0.0}, {0.1, 0.03}, {0.4, 0.05}, {0.55, 0.4}, {1.0, 0.7}}},
        // MR (T1): dark CSF and background transparent, white matter brightest.
        {"mr-default",
         {{0.0, {0.0, 0.0, 0.0}},
          {0.2, {0.45, 0.3, 0.28}},
          {0.5, {0.85, 0.75, 0.68}},
          {1.0, {1.0, 1.0, 1.0}}},
         {{0.0, 0.0}, {0.15, 0.0}, {0.35, 0.02}, {0.7, 0.08}, {1.0, 0.2}}},
        // Grayscale: a linear ramp of brightness and opacity.
        {"grayscale", {{0.0, {0.0, 0.0, 0.0}}, {1.0, {1.0, 1.0, 1.0}}}, {{0.0, 0.0}, {1.0, 0.2}}},
    };
    return kPresets;
}

}  // namespace

std::vector<std::string> TransferFunction::preset_names() {
    std::vector<std::string> names;
    for (const auto& p : presets()) names.emplace_back(p.name);
    for (const auto* p = embedded::kSlicerPresets; (*p)[0] != nullptr; ++p) names.emplace_back((*p)[0]);
    return names;
}

TransferFunction TransferFunction::preset(std::string_view name, std::array<double, 2> value_range) {
    const auto& all = presets();
    const auto it = std::find_if(all.begin(), all.end(), [&](const PresetDef& p) { return p.name == name; });
    if (it == all.end()) {
        // A Slicer preset: absolute units, not scaled to the value range.
        for (const auto* p = embedded::kSlicerPresets; (*p)[0] != nullptr; ++p)
            if (name == (*p)[0]) return from_json_text((*p)[1], "preset '" + std::string(name) + "'");
        std::string list, hint;
        for (const auto& n : preset_names()) {
            list += (list.empty() ? "" : ", ") + n;
            if (hint.empty() && io::iequals(n, name))
                hint = " (names are case-sensitive: did you mean '" + n + "'?)";
        }
        throw Error("preset '" + std::string(name) + "'", "unknown preset" + hint + " (known: " + list + ")");
    }
    const double lo = value_range[0];
    const double span = value_range[1] > lo ? value_range[1] - lo : 1.0;
    TransferFunction tf;
    tf.name = it->name;
    tf.alpha_kind = Alpha::opacity;
    for (const auto& [v, a] : it->opacity) tf.alpha_points.push_back({lo + v * span, a});
    for (const auto& [v, c] : it->color) tf.color_points.push_back({lo + v * span, c});
    return tf;
}

}  // namespace fathom
