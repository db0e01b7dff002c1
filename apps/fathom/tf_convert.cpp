// fathom tf-convert IN OUT.json [--name NAME] [--to fathom|paraview]
// [--range LO,HI]: a transfer function from any supported file (fathom-tf/1,
// a 3D Slicer presets.xml, a ParaView colormap JSON) or a preset name,
// written as fathom-tf/1 or as a ParaView colormap (docs/cli.md).
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/tf_interchange.h"
#include "fathom/transfer_function.h"

#include "commands.h"

namespace fathom::cli {
namespace {

namespace fs = std::filesystem;

struct ConvertArgs {
    std::string input, output, name, to = "fathom", range;
};

std::array<double, 2> parse_tf_range(const std::string& text) {
    double lo = 0, hi = 0;
    char comma = 0;
    std::istringstream ss(text);
    if (!(ss >> lo >> comma >> hi) || comma != ',' || !(hi > lo) || !ss.eof())
        throw UsageError("--range expects LO,HI with HI > LO");
    return {lo, hi};
}

void run_convert(const ConvertArgs& a) {
    std::string ext = fs::path(a.output).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    if (ext != ".json")
        throw UsageError("tf-convert writes JSON: the output must end in .json, got '" + a.output + "'");
    std::array<double, 2> range{0.0, 1.0};
    if (!a.range.empty()) range = parse_tf_range(a.range);

    TransferFunction tf;
    std::error_code ec;
    if (fs::exists(a.input, ec)) {
        if (!a.range.empty()) throw UsageError("--range goes with a preset name, not with a file");
        tf = read_transfer_function(a.input, a.name);
    } else {
        const auto names = TransferFunction::preset_names();
        if (std::find(names.begin(), names.end(), a.input) == names.end()) {
            std::string list;
            for (const auto& n : names) list += (list.empty() ? "" : ", ") + n;
            throw Error(a.input, "no such file, and not a preset name (presets: " + list + ")");
        }
        if (!a.name.empty()) throw UsageError("--name selects within a file, not within a preset");
        tf = TransferFunction::preset(a.input, range);
    }

    std::string text;
    if (a.to == "paraview") {
        try {
            text = to_paraview_json(tf);
        } catch (const Error& e) {
            throw Error(a.input, e.reason());
        }
    } else {
        text = tf.to_json() + "\n";
    }
    write_text_file(a.output, text);
    const std::string what = (a.to == "paraview" ? "ParaView colormap" : "fathom-tf/1") +
                             (tf.name.empty() ? std::string() : " '" + tf.name + "'");
    std::printf("wrote %s (%s)\n", a.output.c_str(), what.c_str());
}

}  // namespace

void add_tf_convert_command(CLI::App& app) {
    auto* cmd = app.add_subcommand(
        "tf-convert",
        "Convert a transfer function (fathom-tf/1, 3D Slicer presets.xml, ParaView colormap JSON, or a "
        "preset name) to fathom-tf/1 or ParaView colormap JSON");
    auto a = std::make_shared<ConvertArgs>();
    cmd->add_option("input", a->input,
                    "Input: a transfer-function file (format found from its content) or a preset name")
        ->required();
    cmd->add_option("output", a->output, "Output file (.json)")->required();
    cmd->add_option(
        "--name", a->name,
        "The preset (Slicer presets file) or colormap (ParaView file) to take; default the first");
    cmd->add_option("--to", a->to, "Output format: fathom (fathom-tf/1, default) or paraview")
        ->check(CLI::IsMember({"fathom", "paraview"}));
    cmd->add_option("--range", a->range,
                    "LO,HI: the value range a normalised fathom preset is scaled to (default 0,1)");
    cmd->callback([a] { run_convert(*a); });
}

}  // namespace fathom::cli
