// fathom info VOLUME: what a volume file holds (dims, type, placement,
// value range and a text histogram; the series of a DICOM folder, the grids
// of an OpenVDB file). fathom convert IN OUT: any readable volume to NRRD.
#include "fathom/info.h"

#include <cstdio>
#include <filesystem>
#include <memory>
#include <string>

#include "fathom/error.h"
#include "fathom/io.h"

#include "commands.h"

namespace fathom::cli {
namespace {

namespace fs = std::filesystem;

struct VolumeArgs {
    std::string path;
    ReadOptions options;
};

void add_volume_args(CLI::App* cmd, VolumeArgs& a, const std::string& what) {
    cmd->add_option("volume", a.path,
                    what +
                        ": NRRD, MetaImage, NIfTI, DICOM (file or folder), OpenVDB, SLC, VTK legacy or "
                        "XML .vti, raw named name_XxYxZ_type.raw")
        ->required();
    cmd->add_option("--series", a.options.series, "DICOM SeriesInstanceUID (a folder with several series)");
    cmd->add_option("--grid", a.options.grid, "OpenVDB grid name (default density)");
}

bool is_dicom(const fs::path& p) {
    std::error_code ec;
    if (fs::is_directory(p, ec)) return true;
    std::string ext = p.extension().string();
    for (char& c : ext) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    if (ext == ".dcm") return true;
    std::FILE* f = std::fopen(p.c_str(), "rb");
    if (!f) return false;
    char head[132] = {};
    const std::size_t n = std::fread(head, 1, sizeof head, f);
    std::fclose(f);
    return n == sizeof head && std::string(head + 128, 4) == "DICM";
}

bool is_vdb(const fs::path& p) {
    if (p.extension() == ".vdb") return true;
    std::FILE* f = std::fopen(p.c_str(), "rb");
    if (!f) return false;
    char head[4] = {};
    const std::size_t n = std::fread(head, 1, sizeof head, f);
    std::fclose(f);
    return n == 4 && std::string(head, 4) == " BDV";
}

/// Prints the series of a DICOM folder; returns false when a volume cannot
/// be chosen (several series and no --series).
bool print_dicom_series(const VolumeArgs& a) {
    const auto series = list_dicom_series(a.path);
    std::printf("DICOM series in %s: %zu\n", a.path.c_str(), series.size());
    for (const auto& s : series)
        std::printf("  %s  %s  %lldx%lld x %zu files  %s\n", s.uid.c_str(),
                    s.modality.empty() ? "?" : s.modality.c_str(), static_cast<long long>(s.columns),
                    static_cast<long long>(s.rows), s.files.size(), s.description.c_str());
    if (series.size() > 1 && a.options.series.empty()) {
        std::printf("Choose one with --series UID to describe it.\n");
        return false;
    }
    std::printf("\n");
    return true;
}

void print_vdb_grids(const VolumeArgs& a) {
    const auto grids = list_vdb_grids(a.path);
    std::printf("OpenVDB grids in %s: %zu\n", a.path.c_str(), grids.size());
    for (const auto& g : grids)
        std::printf("  %-16s %-8s %llu active voxels, index box [%lld %lld %lld] .. [%lld %lld %lld]\n",
                    g.name.c_str(), g.type.c_str(), static_cast<unsigned long long>(g.active_voxels),
                    static_cast<long long>(g.bbox_min[0]), static_cast<long long>(g.bbox_min[1]),
                    static_cast<long long>(g.bbox_min[2]), static_cast<long long>(g.bbox_max[0]),
                    static_cast<long long>(g.bbox_max[1]), static_cast<long long>(g.bbox_max[2]));
    std::printf("\n");
}

}  // namespace

void add_info_command(CLI::App& app) {
    auto* cmd = app.add_subcommand(
        "info",
        "Describe a volume file: dims, type, spacing, origin, orientation, value range, histogram (and the "
        "series of a DICOM folder, the grids of an OpenVDB file)");
    auto a = std::make_shared<VolumeArgs>();
    add_volume_args(cmd, *a, "Volume");
    cmd->callback([a] {
        if (is_dicom(a->path)) {
            if (!print_dicom_series(*a)) return;
        } else if (is_vdb(a->path)) {
            print_vdb_grids(*a);
        }
        const Volume v = read_volume(a->path, a->options);
        std::fputs(describe_volume(v, a->path).c_str(), stdout);
    });
}

void add_convert_command(CLI::App& app) {
    auto* cmd = app.add_subcommand(
        "convert", "Convert any readable volume to NRRD (gzip), which 3D Slicer and ParaView open");
    auto a = std::make_shared<VolumeArgs>();
    auto out = std::make_shared<std::string>();
    auto raw = std::make_shared<bool>(false);
    add_volume_args(cmd, *a, "Input volume");
    cmd->add_option("output", *out, "Output file (.nrrd)")->required();
    cmd->add_flag("--raw", *raw, "Write uncompressed data (default gzip)");
    cmd->callback([a, out, raw] {
        std::string ext = fs::path(*out).extension().string();
        if (ext != ".nrrd")
            throw UsageError("convert writes NRRD: the output must end in .nrrd, got '" + *out + "'");
        const Volume v = read_volume(a->path, a->options);
        write_nrrd(*out, v, !*raw);
        std::printf("wrote %s (%lldx%lldx%lld %s, %d component%s)\n", out->c_str(),
                    static_cast<long long>(v.dims()[0]), static_cast<long long>(v.dims()[1]),
                    static_cast<long long>(v.dims()[2]), std::string(dtype_name(v.dtype())).c_str(),
                    v.components(), v.components() > 1 ? "s" : "");
    });
}

}  // namespace fathom::cli
