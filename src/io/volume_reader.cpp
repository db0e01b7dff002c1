// read_volume: finds a volume file's format from its content (magic bytes),
// then its extension, then the raw naming convention (SPEC §7).
#include <array>
#include <string>
#include <string_view>

#include "fathom/error.h"
#include "fathom/io.h"

#include "io/io_util.h"

namespace fathom {
namespace {

using Reader = Volume (*)(const std::filesystem::path&);

constexpr std::string_view kSupported =
    "supported: NRRD (.nrrd, .nhdr), MetaImage (.mhd, .mha), NIfTI (.nii, .nii.gz, .hdr), DICOM (a "
    "file or a folder of one series), OpenVDB (.vdb), SLC (.slc), legacy VTK structured points "
    "(.vtk), VTK XML ImageData (.vti), and raw files named NAME_XxYxZ_TYPE.raw or .raw.gz, TYPE one of "
    "uint8, int8, uint16, int16, uint32, int32, float32, float64 with an optional be/le "
    "suffix, e.g. head_256x256x128_uint16le.raw";

/// The first non-empty line reads "Key = ..." with a key MetaImage headers start with.
bool looks_like_metaimage(std::string_view head) {
    static constexpr std::array<std::string_view, 10> kKeys{
        "objecttype", "objectsubtype", "ndims",       "comment",      "dimsize", "name",
        "id",         "parentid",      "elementtype", "transformtype"};
    for (auto line : io::split_lines(head)) {
        line = io::trim(line);
        if (line.empty()) continue;
        const std::size_t eq = line.find('=');
        if (eq == std::string_view::npos) return false;
        const std::string key = io::to_lower(io::trim(line.substr(0, eq)));
        for (auto k : kKeys)
            if (key == k) return true;
        return false;
    }
    return false;
}

/// SLC: the magic number 11111 as the first whitespace-separated token.
bool looks_like_slc(std::string_view head) {
    const auto tokens = io::split_ws(head.substr(0, 64));
    return tokens.size() > 1 && tokens[0] == "11111";
}

/// VTK XML: a <VTKFile element near the start (the reader checks its type).
bool looks_like_vtk_xml(std::string_view head) {
    const std::string_view t = io::trim(head);
    return (t.starts_with("<?xml") || t.starts_with("<VTKFile") || t.starts_with("<!--")) &&
           head.find("<VTKFile") != std::string_view::npos;
}

/// NIfTI: sizeof_hdr 348 (NIfTI-1) or 540 (NIfTI-2) in either byte order,
/// with the magic "n+1"/"ni1" at byte 344 or "n+2"/"ni2" at byte 4.
bool looks_like_nifti(std::string_view head) {
    if (head.size() >= 348 && (head.substr(344, 4) == std::string_view("n+1\0", 4) ||
                               head.substr(344, 4) == std::string_view("ni1\0", 4)))
        return true;
    return head.size() >= 540 && (head.substr(4, 4) == std::string_view("n+2\0", 4) ||
                                  head.substr(4, 4) == std::string_view("ni2\0", 4));
}

/// DICOM Part 10: the preamble's 128 bytes, then "DICM".
bool looks_like_dicom(std::string_view head) {
    return head.size() >= 132 && head.substr(128, 4) == "DICM";
}

/// OpenVDB: the magic number 0x56444220 (" BDV" little-endian) first.
bool looks_like_vdb(std::string_view head) {
    return head.starts_with(std::string_view(" BDV", 4));
}

/// Reader for a content signature, or nullptr.
Reader reader_by_content(std::string_view head) {
    if (head.starts_with("NRRD000")) return &read_nrrd;
    if (looks_like_nifti(head)) return &read_nifti;
    if (io::to_lower(head.substr(0, 14)) == "# vtk datafile") return &read_legacy_vtk;
    if (looks_like_vtk_xml(head)) return &read_vti;
    if (looks_like_slc(head)) return &read_slc;
    if (looks_like_metaimage(head)) return &read_metaimage;
    return nullptr;
}

/// Reader for an extension (lower case, with the dot), or nullptr.
Reader reader_by_extension(const std::string& ext) {
    static constexpr std::array<std::pair<std::string_view, Reader>, 9> kByExtension{{
        {".nii", &read_nifti},
        {".hdr", &read_nifti},
        {".nrrd", &read_nrrd},
        {".nhdr", &read_nrrd},
        {".mhd", &read_metaimage},
        {".mha", &read_metaimage},
        {".slc", &read_slc},
        {".vtk", &read_legacy_vtk},
        {".vti", &read_vti},
    }};
    for (const auto& [e, r] : kByExtension)
        if (e == ext) return r;
    return nullptr;
}

}  // namespace

Volume read_volume(const std::filesystem::path& path, const ReadOptions& options) {
    const std::string subject = path.string();
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec)) return read_dicom(path, options.series);
    if (io::file_size_checked(subject, path, "file") == 0) throw Error(subject, "the file is empty");
    const std::string head = io::read_prefix(subject, path, 4096);
    const std::string name = io::to_lower(path.filename().string());
    if (looks_like_vdb(head) || name.ends_with(".vdb"))
        return read_vdb(path, options.grid.empty() ? "density" : options.grid);
    if (looks_like_dicom(head) || name.ends_with(".dcm")) return read_dicom(path, options.series);
    if (name.ends_with(".nii.gz")) return read_nifti(path);
    if (Reader r = reader_by_content(head)) return r(path);
    if (Reader r = reader_by_extension(io::to_lower(path.extension().string()))) return r(path);
    if (auto layout = infer_raw_layout(path)) return read_raw(path, *layout);
    if (name.ends_with(".raw") || name.ends_with(".raw.gz"))
        throw Error(subject,
                    "a raw file's layout is not in its name: name it NAME_XxYxZ_TYPE.raw (e.g. "
                    "head_256x256x128_uint16le.raw) or give dims and dtype in a scene file");
    throw Error(subject, "unrecognised volume format; " + std::string(kSupported));
}

}  // namespace fathom
