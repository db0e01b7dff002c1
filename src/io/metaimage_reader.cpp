// MetaImage reader (.mhd + data file, .mha with LOCAL data), as ITK's MetaIO
// writes it. Placement: node (i,j,k) at Offset + M·(i,j,k) with column a of M
// = ElementSpacing[a] · (TransformMatrix[3a], [3a+1], [3a+2]): MetaIO lists
// the direction of the first axis first (itk::MetaImageIO reads
// TransformMatrix[3a+r] into GetDirection(a)[r]). World coordinates are taken
// as stored (ITK's world is LPS); AnatomicalOrientation is ignored.
#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fathom/error.h"
#include "fathom/io.h"

#include "io/io_util.h"

namespace fathom {
namespace {

struct MetaHeader {
    std::map<std::string, std::string> fields;  // lower-case key → value
    std::vector<std::string> list_files;        // lines after "ElementDataFile = LIST"
    std::uint64_t data_start = 0;               // just after the ElementDataFile line
};

/// Adds "Key = Value"; returns true for ElementDataFile (the last field).
bool add_line(const std::string& subject, MetaHeader& h, std::string_view line, std::size_t line_no) {
    const std::size_t eq = line.find('=');
    if (eq == std::string_view::npos || io::trim(line.substr(0, eq)).empty())
        throw Error(subject, "header line " + std::to_string(line_no) + " is not 'Key = Value': '" +
                                 std::string(line.substr(0, 60)) + "'");
    const std::string key = io::to_lower(io::trim(line.substr(0, eq)));
    if (!h.fields.emplace(key, std::string(io::trim(line.substr(eq + 1)))).second)
        throw Error(subject, "field '" + std::string(io::trim(line.substr(0, eq))) + "' appears twice");
    return key == "elementdatafile";
}

/// Parses the header from a prefix of the file; nullopt when more text is needed.
std::optional<MetaHeader> parse_header(const std::string& subject, std::string_view text, bool whole) {
    MetaHeader h;
    std::size_t begin = 0;
    bool in_list = false;
    for (std::size_t line_no = 1; begin < text.size(); ++line_no) {
        const std::size_t nl = text.find('\n', begin);
        if (nl == std::string_view::npos && !whole) return std::nullopt;
        const std::size_t end = nl == std::string_view::npos ? text.size() : nl;
        const std::string_view line = io::trim(text.substr(begin, end - begin));
        begin = end + 1;
        if (in_list) {
            if (h.list_files.size() >= io::kMaxDataFiles)
                throw Error(subject, "field 'ElementDataFile': LIST names more than " +
                                         std::to_string(io::kMaxDataFiles) + " files");
            if (!line.empty()) h.list_files.emplace_back(line);
        } else if (!line.empty() && add_line(subject, h, line, line_no)) {
            h.data_start = std::min<std::uint64_t>(begin, text.size());
            const auto tokens = io::split_ws(h.fields["elementdatafile"]);
            in_list = !tokens.empty() && io::iequals(tokens[0], "LIST");
            if (!in_list) return h;
        }
    }
    if (!whole) return std::nullopt;
    if (!in_list) throw Error(subject, "missing required field 'ElementDataFile'");
    return h;
}

DType parse_element_type(const std::string& subject, std::string_view value) {
    static const std::map<std::string, DType, std::less<>> kTypes{
        {"met_uchar", DType::u8},  {"met_char", DType::i8},    {"met_ushort", DType::u16},
        {"met_short", DType::i16}, {"met_uint", DType::u32},   {"met_int", DType::i32},
        {"met_ulong", DType::u32}, {"met_long", DType::i32},  // MetaIO's LONG is 4 bytes
        {"met_float", DType::f32}, {"met_double", DType::f64},
    };
    const std::string v = io::to_lower(value);
    if (auto it = kTypes.find(v); it != kTypes.end()) return it->second;
    if (v == "met_long_long" || v == "met_ulong_long")
        throw Error(subject, "field 'ElementType': 64-bit integer samples (" + std::string(value) +
                                 ") are unsupported");
    throw Error(subject, "field 'ElementType': unknown type '" + std::string(value) +
                             "' (MET_UCHAR, MET_CHAR, MET_USHORT, MET_SHORT, MET_UINT, MET_INT, MET_FLOAT or "
                             "MET_DOUBLE)");
}

class MetaImageReader {
public:
    explicit MetaImageReader(const std::filesystem::path& path)
        : path_(path),
          subject_(path.string()),
          h_(io::parse_growing_prefix(subject_, path, [this](std::string_view text, bool whole) {
              return parse_header(subject_, text, whole);
          })) {}

    Volume read() {
        const io::GridShape shape = parse_shape();
        io::grid_bytes(subject_, "DimSize", shape);
        io::DataSpec spec = parse_data_spec();
        const Mat3 axes = parse_axes();
        const Vec3 origin = parse_origin();
        const auto files = data_files();
        if (files.size() > 1) spec.compressed_bytes.reset();  // CompressedDataSize describes one stream
        Volume v = io::read_grid(subject_, shape, files, spec);
        v.set_axes(axes, subject_);
        v.set_origin(origin);
        return v;
    }

private:
    /// The first of the given keys (aliases) that is present.
    std::optional<std::pair<std::string, std::string_view>> get(
        std::initializer_list<const char*> keys) const {
        for (const char* k : keys)
            if (auto it = h_.fields.find(io::to_lower(k)); it != h_.fields.end())
                return std::pair{std::string(k), std::string_view(it->second)};
        return std::nullopt;
    }
    std::string_view require(const char* key) const {
        if (auto v = get({key})) return v->second;
        throw Error(subject_, "missing required field '" + std::string(key) + "'");
    }
    bool flag(std::initializer_list<const char*> keys, bool fallback) const {
        const auto v = get(keys);
        return v ? io::field_bool(subject_, v->first, v->second) : fallback;
    }

    io::GridShape parse_shape();
    io::DataSpec parse_data_spec();
    Mat3 parse_axes() const;
    Vec3 parse_origin() const;
    std::vector<io::DataFile> data_files() const;

    std::filesystem::path path_;
    std::string subject_;
    MetaHeader h_;
    std::vector<std::int64_t> sizes_;
    std::int64_t header_size_ = 0;
};

io::GridShape MetaImageReader::parse_shape() {
    if (auto t = get({"ObjectType"}); t && !io::iequals(t->second, "Image"))
        throw Error(subject_, "field 'ObjectType': expected Image, got '" + std::string(t->second) + "'");
    const std::string_view ndims = require("NDims");
    if (io::parse_int(ndims) != 3)
        throw Error(subject_, "field 'NDims': expected 3, got '" + std::string(ndims) + "'");
    sizes_ = io::field_ints(subject_, "DimSize", require("DimSize"), 3, 1);
    io::GridShape shape{
        {sizes_[0], sizes_[1], sizes_[2]}, parse_element_type(subject_, require("ElementType")), 1};
    if (auto c = get({"ElementNumberOfChannels"})) {
        const auto n = io::parse_int(c->second);
        if (n != 1 && n != 3)
            throw Error(subject_, "field 'ElementNumberOfChannels': expected 1 or 3, got '" +
                                      std::string(c->second) + "'");
        shape.components = static_cast<int>(*n);
    }
    return shape;
}

io::DataSpec MetaImageReader::parse_data_spec() {
    io::DataSpec spec;
    const bool binary = flag({"BinaryData"}, true);
    const bool compressed = flag({"CompressedData"}, false);
    if (compressed && !binary)
        throw Error(subject_, "field 'CompressedData': compressed ASCII data is unsupported");
    spec.encoding = !binary ? io::Encoding::ascii : (compressed ? io::Encoding::zlib : io::Encoding::raw);
    spec.big_endian = flag({"BinaryDataByteOrderMSB", "ElementByteOrderMSB"}, false);
    if (auto s = get({"CompressedDataSize"}); s && compressed)
        spec.compressed_bytes = static_cast<std::uint64_t>(io::field_int(subject_, s->first, s->second, 1));
    if (auto s = get({"HeaderSize"})) {
        header_size_ = io::field_int(subject_, s->first, s->second, -1);
        spec.data_at_end = header_size_ == -1;
    }
    return spec;
}

Mat3 MetaImageReader::parse_axes() const {
    Vec3 s{1, 1, 1};
    if (auto e = get({"ElementSpacing", "ElementSize"})) {
        const auto v = io::field_doubles(subject_, e->first, e->second, 3);
        for (int a = 0; a < 3; ++a) {
            if (!std::isfinite(v[a]) || v[a] == 0.0)
                throw Error(subject_, "field '" + e->first + "': expected 3 non-zero numbers, got '" +
                                          std::string(e->second) + "'");
            s[a] = v[a];
        }
    }
    const auto m = get({"TransformMatrix", "Rotation", "Orientation"});
    if (!m) return Mat3::diagonal(s);
    const auto t = io::field_doubles(subject_, m->first, m->second, 9);
    std::array<Vec3, 3> cols;
    for (std::size_t a = 0; a < 3; ++a)
        cols[a] = Vec3{t[3 * a], t[3 * a + 1], t[3 * a + 2]} * s[static_cast<int>(a)];
    const Mat3 axes = Mat3::from_columns(cols[0], cols[1], cols[2]);
    if (!std::isfinite(axes.determinant()) || axes.determinant() == 0.0)
        throw Error(subject_, "field '" + m->first + "': the matrix is singular or not finite");
    return axes;
}

Vec3 MetaImageReader::parse_origin() const {
    const auto o = get({"Offset", "Origin", "Position", "ImagePosition"});
    if (!o) return {0, 0, 0};
    const auto v = io::field_doubles(subject_, o->first, o->second, 3);
    for (double x : v)
        if (!std::isfinite(x)) throw Error(subject_, "field '" + o->first + "': numbers must be finite");
    return {v[0], v[1], v[2]};
}

std::vector<io::DataFile> MetaImageReader::data_files() const {
    const std::string_view value = require("ElementDataFile");
    const auto tokens = io::split_ws(value);
    const std::uint64_t start = header_size_ > 0 ? static_cast<std::uint64_t>(header_size_) : 0;
    if (io::iequals(value, "LOCAL"))
        return {io::DataFile{path_, header_size_ > 0 ? start : h_.data_start, true}};
    std::vector<std::filesystem::path> paths;
    if (!tokens.empty() && io::iequals(tokens[0], "LIST")) {
        const auto expected = io::files_for_subdim(subject_, "ElementDataFile", sizes_,
                                                   tokens.size() > 1 ? tokens[1] : std::string_view{});
        if (h_.list_files.size() != expected)
            throw Error(subject_, "field 'ElementDataFile': LIST names " +
                                      std::to_string(h_.list_files.size()) + " files, expected " +
                                      std::to_string(expected));
        for (const auto& f : h_.list_files) paths.push_back(io::resolve_beside(path_, f));
    } else if ((tokens.size() == 4 || tokens.size() == 5) && tokens[0].find('%') != std::string_view::npos) {
        const auto min = io::parse_int(tokens[1]), max = io::parse_int(tokens[2]),
                   step = io::parse_int(tokens[3]);
        if (!min || !max || !step)
            throw Error(subject_, "field 'ElementDataFile': expected 'FORMAT MIN MAX STEP', got '" +
                                      std::string(value) + "'");
        paths = io::expand_pattern(subject_, "ElementDataFile", path_, tokens[0], *min, *max, *step,
                                   io::files_for_subdim(subject_, "ElementDataFile", sizes_,
                                                        tokens.size() == 5 ? tokens[4] : std::string_view{}));
    } else {
        paths.push_back(io::resolve_beside(path_, value));
    }
    std::vector<io::DataFile> files;
    files.reserve(paths.size());
    for (auto& p : paths) files.push_back(io::DataFile{std::move(p), start, false});
    return files;
}

}  // namespace

Volume read_metaimage(const std::filesystem::path& path) {
    return MetaImageReader(path).read();
}

}  // namespace fathom
