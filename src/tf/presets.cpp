// Built-in transfer-function presets. Each is written over the normalised
// scalar range [0, 1] and scaled to the value range of the volume it is
// applied to (as ParaView rescales a colormap to the data range), so one
// preset serves a uint8 CT, a 12-bit CT and a float field alike. The
// positions were chosen by looking at the histograms and renders of the CT
// and MR scans fathom is tested on (docs/presets.md).
#include <algorithm>

#include "fathom/error.h"
#include "fathom/transfer_function.h"

namespace fathom {
namespace {

struct PresetDef {
    const char* name;
    std::vector<std::pair<double, Rgb>> color;
    std::vector<std::pair<double, double>> opacity;  // opacity per voxel (unit distance = smallest spacing)
};

const std::vector<PresetDef>& presets() {
    static const std::vector<PresetDef> kPresets = {
        {"ct-bone",
         {{0.0, {0.0, 0.0, 0.0}}, {0.45, {0.55, 0.25, 0.15}}, {0.6, {0.95, 0.88, 0.75}}, {1.0, {1.0, 1.0, 0.95}}},
         {{0.0, 0.0}, {0.45, 0.0}, {0.6, 0.5}, {1.0, 0.9}}},
        {"ct-skin",
         {{0.0, {0.0, 0.0, 0.0}}, {0.2, {0.75, 0.45, 0.35}}, {0.45, {0.95, 0.75, 0.6}}, {1.0, {1.0, 1.0, 0.95}}},
         {{0.0, 0.0}, {0.18, 0.0}, {0.25, 0.08}, {0.45, 0.1}, {0.6, 0.6}, {1.0, 0.8}}},
        {"ct-soft-tissue",
         {{0.0, {0.0, 0.0, 0.0}}, {0.3, {0.6, 0.2, 0.15}}, {0.45, {0.85, 0.45, 0.35}}, {0.6, {1.0, 0.95, 0.85}},
          {1.0, {1.0, 1.0, 1.0}}},
         {{0.0, 0.0}, {0.3, 0.0}, {0.4, 0.05}, {0.5, 0.08}, {0.6, 0.4}, {1.0, 0.6}}},
        {"mr-default",
         {{0.0, {0.0, 0.0, 0.0}}, {0.3, {0.55, 0.35, 0.3}}, {0.6, {0.9, 0.8, 0.7}}, {1.0, {1.0, 1.0, 1.0}}},
         {{0.0, 0.0}, {0.15, 0.0}, {0.4, 0.05}, {0.7, 0.2}, {1.0, 0.4}}},
        {"grayscale", {{0.0, {0.0, 0.0, 0.0}}, {1.0, {1.0, 1.0, 1.0}}}, {{0.0, 0.0}, {1.0, 0.2}}},
    };
    return kPresets;
}

}  // namespace

std::vector<std::string> TransferFunction::preset_names() {
    std::vector<std::string> names;
    for (const auto& p : presets()) names.emplace_back(p.name);
    return names;
}

TransferFunction TransferFunction::preset(std::string_view name, std::array<double, 2> value_range) {
    const auto& all = presets();
    const auto it = std::find_if(all.begin(), all.end(), [&](const PresetDef& p) { return p.name == name; });
    if (it == all.end()) {
        std::string list;
        for (const auto& n : preset_names()) list += (list.empty() ? "" : ", ") + n;
        throw Error("preset '" + std::string(name) + "'", "unknown preset (known: " + list + ")");
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
