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
    "supported: NRRD (.nrrd, .nhdr), MetaImage (.mhd, .mha), SLC (.slc), legacy VTK structured points "
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

/// Reader for a content signature, or nullptr.
Reader reader_by_content(std::string_view head) {
    if (head.starts_with("NRRD000")) return &read_nrrd;
    if (io::to_lower(head.substr(0, 14)) == "# vtk datafile") return &read_legacy_vtk;
    if (looks_like_vtk_xml(head)) return &read_vti;
    if (looks_like_slc(head)) return &read_slc;
    if (looks_like_metaimage(head)) return &read_metaimage;
    return nullptr;
}

/// Reader for an extension (lower case, with the dot), or nullptr.
Reader reader_by_extension(const std::string& ext) {
    static constexpr std::array<std::pair<std::string_view, Reader>, 7> kByExtension{{
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

Volume read_volume(const std::filesystem::path& path) {
    const std::string subject = path.string();
    std::error_code ec;
    if (std::filesystem::is_directory(path, ec))
        throw Error(subject, "is a directory: DICOM series are not supported yet");
    if (io::file_size_checked(subject, path, "file") == 0) throw Error(subject, "the file is empty");
    if (Reader r = reader_by_content(io::read_prefix(subject, path, 4096))) return r(path);
    const std::string name = io::to_lower(path.filename().string());
    if (Reader r = reader_by_extension(io::to_lower(path.extension().string()))) return r(path);
    if (auto layout = infer_raw_layout(path)) return read_raw(path, *layout);
    if (name.ends_with(".raw") || name.ends_with(".raw.gz"))
        throw Error(subject,
                    "a raw file's layout is not in its name: name it NAME_XxYxZ_TYPE.raw (e.g. "
                    "head_256x256x128_uint16le.raw) or give dims and dtype in a scene file");
    throw Error(subject, "unrecognised volume format; " + std::string(kSupported));
}

}  // namespace fathom
