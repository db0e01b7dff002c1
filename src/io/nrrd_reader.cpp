// NRRD reader (NRRD0001..NRRD0005 as specified by teem): attached (.nrrd) and
// detached (.nhdr) headers; raw, gzip and ascii encodings; single, LIST and
// %d-pattern data files; placement from space directions / spacings and
// space origin, converted to LPS world coordinates (SPEC §2).
#include <array>
#include <cmath>
#include <map>
#include <optional>
#include <set>
#include <string>
#include <string_view>
#include <vector>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"

#include "io/io_util.h"

namespace fathom {
namespace {

struct NrrdHeader {
    std::map<std::string, std::string> fields;  // canonical key ("datafile") → value
    std::vector<std::string> list_files;        // lines after "data file: LIST"
    std::optional<std::uint64_t> data_start;    // just after the blank line that ends the header
};

/// "Data File" → "datafile", "space directions" → "spacedirections".
std::string canonical_key(std::string_view key) {
    std::string r;
    for (char c : io::to_lower(io::trim(key)))
        if (c != ' ' && c != '\t') r += c;
    return r;
}

/// Lower case with single spaces: "unsigned  Short" → "unsigned short".
std::string normalized(std::string_view value) {
    std::string r;
    for (auto t : io::split_ws(value)) {
        if (!r.empty()) r.push_back(' ');
        r.append(io::to_lower(t));
    }
    return r;
}

void check_magic(const std::string& subject, std::string_view text) {
    if (!text.starts_with("NRRD000"))
        throw Error(subject, "not a NRRD file: the first line must be NRRD0001 .. NRRD0005");
    if (text.size() < 8 || text[7] < '1' || text[7] > '5')
        throw Error(subject, "unsupported NRRD version '" + std::string(io::trim(text.substr(0, 8))) +
                                 "' (NRRD0001 .. NRRD0005 are read)");
}

/// One header line: a field ("key: value") or a key/value pair ("key:=value", ignored).
void add_field_line(const std::string& subject, NrrdHeader& h, std::string_view line, std::size_t line_no) {
    const std::size_t kv = line.find(":=");
    const std::size_t colon = line.find(':');
    if (kv != std::string_view::npos && kv == colon) return;
    if (colon == std::string_view::npos || colon == 0)
        throw Error(subject, "header line " + std::to_string(line_no) + " is not 'field: value': '" +
                                 std::string(line.substr(0, 60)) + "'");
    const std::string key = canonical_key(line.substr(0, colon));
    const std::string value(io::trim(line.substr(colon + 1)));
    if (!h.fields.emplace(key, value).second)
        throw Error(subject, "field '" + std::string(io::trim(line.substr(0, colon))) + "' appears twice");
}

bool starts_list(const NrrdHeader& h) {
    const auto it = h.fields.find("datafile");
    if (it == h.fields.end()) return false;
    const auto tokens = io::split_ws(it->second);
    return !tokens.empty() && tokens[0] == "LIST";
}

/// Parses the header from a prefix of the file; nullopt when more text is needed.
std::optional<NrrdHeader> parse_header(const std::string& subject, std::string_view text, bool whole) {
    if (text.size() < 8 && !whole) return std::nullopt;
    check_magic(subject, text);
    NrrdHeader h;
    std::size_t pos = text.find('\n');
    bool in_list = false;
    for (std::size_t line_no = 2; pos != std::string_view::npos && pos + 1 <= text.size(); ++line_no) {
        const std::size_t begin = pos + 1;
        pos = text.find('\n', begin);
        if (pos == std::string_view::npos && !whole) return std::nullopt;
        std::string_view line = text.substr(begin, pos == std::string_view::npos ? pos : pos - begin);
        if (!line.empty() && line.back() == '\r') line.remove_suffix(1);
        if (line.empty()) {
            if (pos != std::string_view::npos)
                h.data_start = pos + 1;
            else if (begin < text.size())
                h.data_start = text.size();
            break;
        }
        if (in_list && h.list_files.size() >= io::kMaxDataFiles)
            throw Error(subject, "field 'data file': LIST names more than " +
                                     std::to_string(io::kMaxDataFiles) + " files");
        if (in_list)
            h.list_files.emplace_back(io::trim(line));
        else if (line[0] != '#')
            add_field_line(subject, h, line, line_no);
        in_list = in_list || starts_list(h);
    }
    return h;
}

// ------------------------------------------------------------ field values

DType parse_type(const std::string& subject, std::string_view value) {
    static const std::map<std::string, DType, std::less<>> kTypes{
        {"signed char", DType::i8},
        {"int8", DType::i8},
        {"int8_t", DType::i8},
        {"uchar", DType::u8},
        {"unsigned char", DType::u8},
        {"uint8", DType::u8},
        {"uint8_t", DType::u8},
        {"short", DType::i16},
        {"short int", DType::i16},
        {"signed short", DType::i16},
        {"signed short int", DType::i16},
        {"int16", DType::i16},
        {"int16_t", DType::i16},
        {"ushort", DType::u16},
        {"unsigned short", DType::u16},
        {"unsigned short int", DType::u16},
        {"uint16", DType::u16},
        {"uint16_t", DType::u16},
        {"int", DType::i32},
        {"signed int", DType::i32},
        {"int32", DType::i32},
        {"int32_t", DType::i32},
        {"uint", DType::u32},
        {"unsigned int", DType::u32},
        {"uint32", DType::u32},
        {"uint32_t", DType::u32},
        {"float", DType::f32},
        {"double", DType::f64},
    };
    static const std::set<std::string, std::less<>> k64{
        "longlong", "long long", "long long int", "signed long long",   "signed long long int",
        "int64",    "int64_t",   "ulonglong",     "unsigned long long", "unsigned long long int",
        "uint64",   "uint64_t"};
    const std::string v = normalized(value);
    if (auto it = kTypes.find(v); it != kTypes.end()) return it->second;
    if (k64.contains(v) || v == "block")
        throw Error(subject, "field 'type': '" + v +
                                 "' samples are unsupported (8-, 16- and 32-bit integers, "
                                 "float and double are read)");
    throw Error(subject, "field 'type': unknown type '" + std::string(value) + "'");
}

io::Encoding parse_encoding(const std::string& subject, std::string_view value) {
    const std::string v = normalized(value);
    if (v == "raw") return io::Encoding::raw;
    if (v == "gzip" || v == "gz") return io::Encoding::zlib;
    if (v == "ascii" || v == "text" || v == "txt") return io::Encoding::ascii;
    const bool known = v == "hex" || v == "bzip2" || v == "bz2" || v == "zrl";
    throw Error(subject, "field 'encoding': " + std::string(known ? "unsupported" : "unknown") +
                             " encoding '" + std::string(value) + "' (raw, gzip and ascii are read)");
}

/// Sign flips that take the header's space to LPS (SPEC §2).
Vec3 space_to_lps(const std::string& subject, std::string_view value) {
    const std::string v = normalized(value);
    if (v == "left-posterior-superior" || v == "lps" || v == "scanner-xyz" || v == "3d-right-handed" ||
        v == "3d-left-handed")
        return {1, 1, 1};
    if (v == "right-anterior-superior" || v == "ras") return {-1, -1, 1};
    if (v == "left-anterior-superior" || v == "las") return {1, -1, 1};
    if (v.ends_with("-time") || v == "rast" || v == "last" || v == "lpst")
        throw Error(subject,
                    "field 'space': '" + std::string(value) + "' (a space with time) is unsupported");
    throw Error(subject, "field 'space': unknown space '" + std::string(value) + "'");
}

/// "(1,0,0) none (0,1,0)" → vectors, nullopt for "none".
std::vector<std::optional<Vec3>> parse_vectors(const std::string& subject, std::string_view field,
                                               std::string_view value) {
    const auto bad = [&] {
        return Error(subject, "field '" + std::string(field) +
                                  "': expected vectors like (x,y,z) or none, got '" + std::string(value) +
                                  "'");
    };
    std::vector<std::optional<Vec3>> out;
    std::string_view rest = io::trim(value);
    while (!rest.empty()) {
        if (rest.starts_with("none")) {
            out.emplace_back(std::nullopt);
            rest = io::trim(rest.substr(4));
            continue;
        }
        const std::size_t close = rest.find(')');
        if (rest.front() != '(' || close == std::string_view::npos) throw bad();
        std::string inner(rest.substr(1, close - 1));
        for (char& c : inner) c = c == ',' ? ' ' : c;
        const auto tokens = io::split_ws(inner);
        std::array<double, 3> v{};
        if (tokens.size() != 3) throw bad();
        for (std::size_t i = 0; i < 3; ++i) {
            const auto d = io::parse_double(tokens[i]);
            if (!d || !std::isfinite(*d)) throw bad();
            v[i] = *d;
        }
        out.emplace_back(Vec3{v[0], v[1], v[2]});
        rest = io::trim(rest.substr(close + 1));
    }
    return out;
}

// ------------------------------------------------------------ the reader

class NrrdReader {
public:
    explicit NrrdReader(const std::filesystem::path& path)
        : path_(path),
          subject_(path.string()),
          h_(io::parse_growing_prefix(subject_, path, [this](std::string_view text, bool whole) {
              return parse_header(subject_, text, whole);
          })) {}

    Volume read() {
        warn_unknown_fields();
        const io::GridShape shape = parse_shape();
        io::grid_bytes(subject_, "sizes", shape);
        check_kinds();
        const io::DataSpec spec = parse_data_spec(shape.dtype);
        const Vec3 flip = lps_flip();
        const Mat3 axes = parse_axes(flip);
        const Vec3 origin = parse_origin(flip);
        Volume v = io::read_grid(subject_, shape, data_files(), spec);
        v.set_axes(axes, subject_);
        v.set_origin(origin);
        return v;
    }

private:
    std::optional<std::string_view> get(const std::string& key) const {
        const auto it = h_.fields.find(key);
        if (it == h_.fields.end()) return std::nullopt;
        return std::string_view(it->second);
    }
    std::string_view require(const std::string& key, const char* name) const {
        if (auto v = get(key)) return *v;
        throw Error(subject_, "missing required field '" + std::string(name) + "'");
    }
    /// Index of the first spatial axis (1 when the first axis holds components).
    [[nodiscard]] std::size_t first_spatial() const { return dim_ == 4 ? 1 : 0; }

    void warn_unknown_fields() const;
    io::GridShape parse_shape();
    void check_kinds() const;
    io::DataSpec parse_data_spec(DType type) const;
    Vec3 lps_flip() const;
    Mat3 parse_axes(const Vec3& flip) const;
    Mat3 axes_from_directions(std::string_view value, const Vec3& flip) const;
    Mat3 axes_from_spacings(std::string_view value) const;
    Vec3 parse_origin(const Vec3& flip) const;
    std::vector<io::DataFile> data_files() const;
    std::uint64_t files_expected(std::string_view subdim_token) const {
        return io::files_for_subdim(subject_, "data file", sizes_, subdim_token);
    }

    std::filesystem::path path_;
    std::string subject_;
    NrrdHeader h_;
    std::size_t dim_ = 3;
    std::vector<std::int64_t> sizes_;
};

void NrrdReader::warn_unknown_fields() const {
    static const std::set<std::string, std::less<>> kKnown{"content",
                                                           "type",
                                                           "dimension",
                                                           "sizes",
                                                           "endian",
                                                           "encoding",
                                                           "byteskip",
                                                           "lineskip",
                                                           "datafile",
                                                           "spacings",
                                                           "spacedirections",
                                                           "spaceorigin",
                                                           "space",
                                                           "spacedimension",
                                                           "kinds",
                                                           "centers",
                                                           "centerings",
                                                           "units",
                                                           "spaceunits",
                                                           "min",
                                                           "max",
                                                           "oldmin",
                                                           "oldmax",
                                                           "sampleunits",
                                                           "labels",
                                                           "thicknesses",
                                                           "axismins",
                                                           "axismaxs",
                                                           "measurementframe",
                                                           "number",
                                                           "blocksize"};
    for (const auto& [key, value] : h_.fields)
        if (!kKnown.contains(key)) warn(subject_ + ": unknown NRRD field '" + key + "' ignored");
}

io::GridShape NrrdReader::parse_shape() {
    const std::string_view dim_text = require("dimension", "dimension");
    const auto dim = io::parse_int(dim_text);
    if (!dim || (*dim != 3 && *dim != 4))
        throw Error(subject_, "field 'dimension': expected 3 (a volume) or 4 (components first), got '" +
                                  std::string(dim_text) + "'");
    dim_ = static_cast<std::size_t>(*dim);
    sizes_ = io::field_ints(subject_, "sizes", require("sizes", "sizes"), dim_, 1);
    if (dim_ == 4 && sizes_[0] != 1 && sizes_[0] != 3)
        throw Error(subject_,
                    "field 'sizes': in a 4-D NRRD the first axis holds the components and must have "
                    "size 1 or 3, got " +
                        std::to_string(sizes_[0]));
    io::GridShape shape;
    for (std::size_t a = 0; a < 3; ++a) shape.dims[a] = sizes_[first_spatial() + a];
    shape.components = dim_ == 4 ? static_cast<int>(sizes_[0]) : 1;
    shape.dtype = parse_type(subject_, require("type", "type"));
    return shape;
}

void NrrdReader::check_kinds() const {
    const auto value = get("kinds");
    if (!value) return;
    const auto kinds = io::split_ws(*value);
    if (kinds.size() != dim_)
        throw Error(subject_, "field 'kinds': expected " + std::to_string(dim_) + " kinds, got '" +
                                  std::string(*value) + "'");
    for (std::size_t a = 0; a < dim_; ++a) {
        const std::string k = io::to_lower(kinds[a]);
        const bool domain = k == "domain" || k == "space";
        if (a < first_spatial() && (domain || k == "time"))
            throw Error(subject_,
                        "field 'kinds': the first axis of a 4-D NRRD holds the components "
                        "(RGB-color, 3-color, vector, ...), not '" +
                            std::string(kinds[a]) + "'");
        if (a >= first_spatial() && !domain && k != "none" && k != "???")
            throw Error(subject_, "field 'kinds': axis " + std::to_string(a) + " is '" +
                                      std::string(kinds[a]) +
                                      "', but a volume axis must be domain, space or none");
    }
}

io::DataSpec NrrdReader::parse_data_spec(DType type) const {
    io::DataSpec spec;
    spec.encoding = parse_encoding(subject_, require("encoding", "encoding"));
    if (auto e = get("endian")) {
        const std::string v = normalized(*e);
        if (v != "little" && v != "big")
            throw Error(subject_, "field 'endian': expected little or big, got '" + std::string(*e) + "'");
        spec.big_endian = v == "big";
    } else if (dtype_size(type) > 1 && spec.encoding != io::Encoding::ascii) {
        throw Error(subject_, "missing required field 'endian' (little or big) for " +
                                  std::string(dtype_name(type)) + " samples");
    }
    if (auto s = get("byteskip")) {
        const std::int64_t skip = io::field_int(subject_, "byte skip", *s, -1);
        spec.data_at_end = skip == -1;
        spec.byte_skip = skip < 0 ? 0 : static_cast<std::uint64_t>(skip);
        if (spec.data_at_end && spec.encoding != io::Encoding::raw)
            throw Error(subject_, "field 'byte skip': -1 (data at the end of the file) needs encoding raw");
    }
    if (auto s = get("lineskip"))
        spec.line_skip = static_cast<std::uint64_t>(io::field_int(subject_, "line skip", *s, 0));
    return spec;
}

Vec3 NrrdReader::lps_flip() const {
    if (auto d = get("spacedimension"); d && io::parse_int(*d) != 3)
        throw Error(subject_, "field 'space dimension': expected 3, got '" + std::string(*d) + "'");
    if (auto s = get("space")) return space_to_lps(subject_, *s);
    return {1, 1, 1};
}

Mat3 NrrdReader::parse_axes(const Vec3& flip) const {
    if (auto d = get("spacedirections")) return axes_from_directions(*d, flip);
    if (auto s = get("spacings")) return axes_from_spacings(*s);
    return Mat3::identity();
}

Mat3 NrrdReader::axes_from_directions(std::string_view value, const Vec3& flip) const {
    const auto vectors = parse_vectors(subject_, "space directions", value);
    if (vectors.size() != dim_ || (dim_ == 4 && vectors[0]))
        throw Error(subject_, "field 'space directions': expected " +
                                  std::string(dim_ == 4 ? "none and 3 vectors" : "3 vectors") + ", got '" +
                                  std::string(value) + "'");
    std::array<Vec3, 3> cols;
    for (std::size_t a = 0; a < 3; ++a) {
        const auto& v = vectors[first_spatial() + a];
        if (!v)
            throw Error(subject_, "field 'space directions': spatial axis " + std::to_string(a) + " is none");
        cols[a] = {v->x * flip.x, v->y * flip.y, v->z * flip.z};
    }
    const Mat3 m = Mat3::from_columns(cols[0], cols[1], cols[2]);
    if (m.determinant() == 0.0)
        throw Error(subject_, "field 'space directions': the axis vectors are degenerate (zero volume)");
    return m;
}

Mat3 NrrdReader::axes_from_spacings(std::string_view value) const {
    const auto tokens = io::split_ws(value);
    Vec3 s{1, 1, 1};
    bool ok = tokens.size() == dim_;
    for (std::size_t a = 0; ok && a < dim_; ++a) {
        const auto d = io::parse_double(tokens[a]);
        if (d && std::isnan(*d)) continue;  // unknown spacing: 1 (the component axis must have none)
        ok = a >= first_spatial() && d && std::isfinite(*d) && *d != 0.0;
        if (ok) s[static_cast<int>(a - first_spatial())] = *d;
    }
    if (!ok)
        throw Error(subject_,
                    "field 'spacings': expected " + std::to_string(dim_) +
                        (dim_ == 4 ? " numbers (nan for the component axis)" : " non-zero numbers") +
                        ", got '" + std::string(value) + "'");
    return Mat3::diagonal(s);
}

Vec3 NrrdReader::parse_origin(const Vec3& flip) const {
    const auto value = get("spaceorigin");
    if (!value) return {0, 0, 0};
    const auto vectors = parse_vectors(subject_, "space origin", *value);
    if (vectors.size() != 1 || !vectors[0])
        throw Error(subject_,
                    "field 'space origin': expected one vector (x,y,z), got '" + std::string(*value) + "'");
    return {vectors[0]->x * flip.x, vectors[0]->y * flip.y, vectors[0]->z * flip.z};
}

std::vector<io::DataFile> NrrdReader::data_files() const {
    const auto value = get("datafile");
    if (!value) {
        if (!h_.data_start)
            throw Error(
                subject_,
                "no data: the header has no 'data file' field and no blank line before attached data");
        return {io::DataFile{path_, *h_.data_start, true}};
    }
    const auto tokens = io::split_ws(*value);
    std::vector<std::filesystem::path> paths;
    if (!tokens.empty() && tokens[0] == "LIST") {
        const std::uint64_t expected = files_expected(tokens.size() > 1 ? tokens[1] : std::string_view{});
        if (h_.list_files.size() != expected)
            throw Error(subject_, "field 'data file': LIST names " + std::to_string(h_.list_files.size()) +
                                      " files, expected " + std::to_string(expected));
        for (const auto& f : h_.list_files) paths.push_back(io::resolve_beside(path_, f));
    } else if (tokens.size() >= 4 && tokens.size() <= 5 && tokens[0].find('%') != std::string_view::npos) {
        const auto min = io::parse_int(tokens[1]), max = io::parse_int(tokens[2]),
                   step = io::parse_int(tokens[3]);
        if (!min || !max || !step)
            throw Error(subject_, "field 'data file': expected 'FORMAT MIN MAX STEP [SUBDIM]', got '" +
                                      std::string(*value) + "'");
        paths = io::expand_pattern(subject_, "data file", path_, tokens[0], *min, *max, *step,
                                   files_expected(tokens.size() == 5 ? tokens[4] : std::string_view{}));
    } else {
        paths.push_back(io::resolve_beside(path_, *value));
    }
    std::vector<io::DataFile> files;
    files.reserve(paths.size());
    for (auto& p : paths) files.push_back(io::DataFile{std::move(p), 0, false});
    return files;
}

}  // namespace

Volume read_nrrd(const std::filesystem::path& path) {
    return NrrdReader(path).read();
}

}  // namespace fathom
