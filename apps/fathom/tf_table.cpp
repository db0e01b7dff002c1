// fathom tf-table TF.json -o table.png: the pre-integration table of a
// transfer function as a picture (opacity | color) or as CSV.
#include <algorithm>
#include <cstdio>
#include <filesystem>
#include <sstream>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/preintegration.h"

#include "commands.h"

namespace fathom::cli {
namespace {

struct TableArgs {
    std::string tf, preset, output, range;
    int size = 256, threads = 0;
    double delta = 1.0, unit = 1.0;
    bool simple = false, csv = false;
};

std::array<double, 2> parse_range(const std::string& text) {
    double lo = 0, hi = 0;
    char comma = 0;
    std::istringstream ss(text);
    if (!(ss >> lo >> comma >> hi) || comma != ',' || !(hi > lo))
        throw UsageError("--range expects LO,HI with HI > LO");
    return {lo, hi};
}

// Picture: left the opacity α, right the segment's color C/α (black where
// α = 0); v_front grows to the right, v_back grows upward.
Image table_image(const PreintegrationTable& t) {
    Image img(2 * t.size, t.size);
    for (int j = 0; j < t.size; ++j)
        for (int i = 0; i < t.size; ++i) {
            const std::size_t k =
                static_cast<std::size_t>(i) + static_cast<std::size_t>(t.size) * static_cast<std::size_t>(j);
            const float a = t.alpha[k];
            float* left = img.pixel(i, t.size - 1 - j);
            float* right = img.pixel(t.size + i, t.size - 1 - j);
            for (int c = 0; c < 3; ++c) {
                left[c] = a;
                right[c] = a > 1e-6f ? t.color[k * 3 + static_cast<std::size_t>(c)] / a : 0.0f;
            }
            left[3] = right[3] = 1.0f;
        }
    return img;
}

std::string table_csv(const PreintegrationTable& t) {
    std::string out = "v_front,v_back,alpha,r,g,b\n";
    char line[256];
    for (int j = 0; j < t.size; ++j)
        for (int i = 0; i < t.size; ++i) {
            const std::size_t k =
                static_cast<std::size_t>(i) + static_cast<std::size_t>(t.size) * static_cast<std::size_t>(j);
            std::snprintf(line, sizeof line, "%.9g,%.9g,%.9g,%.9g,%.9g,%.9g\n", t.v(i), t.v(j), t.alpha[k],
                          t.color[k * 3], t.color[k * 3 + 1], t.color[k * 3 + 2]);
            out += line;
        }
    return out;
}

void run_table(const TableArgs& a) {
    if (a.tf.empty() == a.preset.empty()) throw UsageError("tf-table needs a TF file or --preset (not both)");
    std::string ext = std::filesystem::path(a.output).extension().string();
    std::transform(ext.begin(), ext.end(), ext.begin(), [](unsigned char c) { return std::tolower(c); });
    const bool csv = a.csv || ext == ".csv";
    if (!csv && ext != ".png" && ext != ".pfm" && ext != ".exr")
        throw UsageError("-o " + a.output + ": expected .png, .pfm, .exr, or .csv (or --csv)");
    std::array<double, 2> range{0.0, 1.0};
    if (!a.range.empty()) range = parse_range(a.range);
    const TransferFunction tf =
        a.tf.empty() ? TransferFunction::preset(a.preset, range) : TransferFunction::from_file(a.tf);
    if (a.range.empty() && !a.tf.empty()) {
        // the span of the control points, widened by 5 % on each side
        double lo = tf.alpha_points.front().first, hi = tf.alpha_points.back().first;
        lo = std::min(lo, tf.color_points.front().first);
        hi = std::max(hi, tf.color_points.back().first);
        const double pad = hi > lo ? 0.05 * (hi - lo) : 1.0;
        range = {lo - pad, hi + pad};
    }
    if (!(a.delta > 0) || !(a.unit > 0)) throw UsageError("--delta and --unit-distance must be > 0");
    const Classifier c(tf, a.unit);
    const PreintegrationTable t =
        build_preintegration_table(c, range[0], range[1], a.size, a.delta, !a.simple, a.threads);
    if (csv)
        write_text_file(a.output, table_csv(t));
    else
        write_image(a.output, table_image(t));
}

}  // namespace

void add_tf_table_command(CLI::App& app) {
    auto* cmd = app.add_subcommand(
        "tf-table", "Write the pre-integration table of a transfer function as an image or CSV");
    auto a = std::make_shared<TableArgs>();
    cmd->add_option("tf", a->tf,
                    "Transfer function file (fathom-tf/1, 3D Slicer presets.xml or ParaView colormap JSON)");
    cmd->add_option("--preset", a->preset, "A preset instead of a file (scaled to --range, default 0,1)");
    cmd->add_option("-o,--output", a->output, "Output: .png/.pfm/.exr (opacity | color picture) or .csv")
        ->required();
    cmd->add_flag("--csv", a->csv, "Write CSV (v_front, v_back, alpha, r, g, b) whatever the extension");
    cmd->add_option("--size", a->size, "Entries per axis (default 256)")->check(CLI::Range(2, 4096));
    cmd->add_option("--delta", a->delta, "Segment length in world units (default 1)");
    cmd->add_option("--unit-distance", a->unit, "Opacity unit distance when the TF has none (default 1)");
    cmd->add_option("--range", a->range,
                    "LO,HI scalar range of the table (default: the TF's control points + 5 %)");
    cmd->add_flag("--simple", a->simple, "Without self-attenuation (preintegrated-simple)");
    cmd->add_option("--threads", a->threads, "Threads (default: all cores)")->check(CLI::NonNegativeNumber);
    cmd->callback([a] { run_table(*a); });
}

}  // namespace fathom::cli
