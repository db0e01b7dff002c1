// Headerless (raw) volumes: the layout comes from the caller (a scene file's
// "dims"/"dtype"/...) or from the "name_XxYxZ_type.raw" naming convention.
// A name ending in ".gz" is a gzip stream of the same bytes (header_bytes
// then counts in the decompressed stream).
#include <cmath>
#include <string>
#include <string_view>

#include "fathom/error.h"
#include "fathom/io.h"

#include "io/io_util.h"

namespace fathom {
namespace {

bool ends_with_gz(const std::filesystem::path& path) {
    const std::string name = io::to_lower(path.filename().string());
    return name.size() > 3 && name.ends_with(".gz");
}

void check_placement(const std::string& subject, const RawLayout& layout) {
    for (int a = 0; a < 3; ++a) {
        if (!std::isfinite(layout.spacing[a]) || layout.spacing[a] == 0.0)
            throw Error(subject, "spacing " + std::to_string(a) + " must be finite and non-zero, got " +
                                     std::to_string(layout.spacing[a]));
        if (!std::isfinite(layout.origin[a]))
            throw Error(subject, "origin " + std::to_string(a) + " must be finite");
    }
}

/// "uint16", "uint16be", "float32le", ... → type and byte order.
std::optional<std::pair<DType, bool>> parse_type_token(std::string_view token) {
    if (const auto type = find_dtype(token)) return std::pair{*type, false};  // "double" ends in "le" too
    if (!token.ends_with("be") && !token.ends_with("le")) return std::nullopt;
    const bool big = token.ends_with("be");
    token.remove_suffix(2);
    if (const auto type = find_dtype(token)) return std::pair{*type, big};
    return std::nullopt;
}

/// "256x256x133" → dims; nullopt unless three x-separated integers.
std::optional<std::array<std::int64_t, 3>> parse_dims_token(std::string_view token) {
    std::array<std::int64_t, 3> dims{};
    for (int a = 0; a < 3; ++a) {
        const std::size_t x = a < 2 ? token.find('x') : token.size();
        if (x == std::string_view::npos) return std::nullopt;
        const std::string_view part = token.substr(0, x);
        if (part.empty() || part.find_first_not_of("0123456789") != std::string_view::npos)
            return std::nullopt;
        const auto v = io::parse_int(part);
        if (!v) return std::nullopt;
        dims[a] = *v;
        token.remove_prefix(a < 2 ? x + 1 : x);
    }
    return dims;
}

}  // namespace

Volume read_raw(const std::filesystem::path& path, const RawLayout& layout) {
    const std::string subject = path.string();
    const io::GridShape shape{layout.dims, layout.dtype, layout.components};
    io::grid_bytes(subject, "dims", shape);
    check_placement(subject, layout);
    io::DataSpec spec;
    spec.encoding = ends_with_gz(path) ? io::Encoding::zlib : io::Encoding::raw;
    spec.big_endian = layout.big_endian;
    spec.byte_skip = layout.header_bytes;
    Volume v = io::read_grid(subject, shape, {io::DataFile{path, 0, false}}, spec);
    v.set_spacing(layout.spacing);
    v.set_origin(layout.origin);
    return v;
}

std::optional<RawLayout> infer_raw_layout(const std::filesystem::path& path) {
    std::string name = io::to_lower(path.filename().string());
    if (name.ends_with(".gz")) name.resize(name.size() - 3);
    if (const std::size_t dot = name.rfind('.'); dot != std::string::npos && dot > 0) name.resize(dot);
    std::optional<std::array<std::int64_t, 3>> dims;
    std::optional<std::pair<DType, bool>> type;
    std::string_view rest = name;
    while (!rest.empty()) {
        const std::size_t cut = rest.find('_');
        const std::string_view token = rest.substr(0, cut);
        if (auto d = parse_dims_token(token))
            dims = d;
        else if (auto t = parse_type_token(token))
            type = t;
        if (cut == std::string_view::npos) break;
        rest.remove_prefix(cut + 1);
    }
    if (!dims || !type) return std::nullopt;
    RawLayout layout;
    layout.dims = *dims;
    layout.dtype = type->first;
    layout.big_endian = type->second;
    return layout;
}

}  // namespace fathom
