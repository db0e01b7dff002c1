// Legacy VTK reader (.vtk): DATASET STRUCTURED_POINTS with POINT_DATA SCALARS.
//
//   # vtk DataFile Version x.x
//   a title line
//   ASCII | BINARY
//   DATASET STRUCTURED_POINTS
//   DIMENSIONS nx ny nz
//   SPACING sx sy sz          (or ASPECT_RATIO, the older name)
//   ORIGIN x y z
//   POINT_DATA n
//   SCALARS name type [1]
//   LOOKUP_TABLE name
//   the n samples, x fastest: ASCII numbers, or BINARY big-endian bytes
//   starting after the LOOKUP_TABLE line's newline
//
// The first two lines are read as lines; from the format keyword on, the
// header is whitespace-separated tokens (blank lines anywhere, as in
// ironProt.vtk). Keywords compare without case (as vtkDataReader lowercases
// them); the dataset keywords come in any order. A DIRECTION row-major 3x3 matrix (as in
// VTK XML) is applied to the axes. Other datasets, cell data, field data,
// attributes other than SCALARS first under POINT_DATA, several components
// and 64-bit or bit types are refused. Bytes after the scalars (a trailing
// newline, further attributes) are ignored; anything but whitespace there is
// reported with a warning.
#include <array>
#include <cctype>
#include <cmath>
#include <optional>
#include <string>
#include <string_view>
#include <vector>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"

#include "io/io_util.h"

namespace fathom {
namespace {

struct VtkHeader {
    bool binary = false;
    std::optional<std::array<std::int64_t, 3>> dims;
    Vec3 spacing{1, 1, 1};
    Vec3 origin{0, 0, 0};
    std::optional<std::array<double, 9>> direction;
    std::int64_t points = 0;
    DType dtype = DType::u8;
    std::uint64_t data_start = 0;
};

/// Thrown inside the parser when the prefix ends before the header does.
struct NeedMore {};

/// Whitespace-separated tokens with their positions; the first three lines are read as lines.
class Tokens {
public:
    Tokens(const std::string& subject, std::string_view text, bool whole)
        : subject_(subject), text_(text), whole_(whole) {}

    /// The next line (without "\n" / "\r\n"), for the fixed first lines.
    std::string_view line() {
        const std::size_t nl = text_.find('\n', pos_);
        if (nl == std::string_view::npos) {
            if (!whole_) throw NeedMore{};
            if (pos_ >= text_.size()) ends();
        }
        const std::size_t end = nl == std::string_view::npos ? text_.size() : nl;
        std::string_view l = text_.substr(pos_, end - pos_);
        if (!l.empty() && l.back() == '\r') l.remove_suffix(1);
        pos_ = nl == std::string_view::npos ? text_.size() : nl + 1;
        return l;
    }
    std::string_view next() {
        while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
        const std::size_t b = pos_;
        while (pos_ < text_.size() && !std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
        if (pos_ == text_.size() && !whole_) throw NeedMore{};
        if (pos_ == b) ends();
        return text_.substr(b, pos_ - b);
    }
    std::string keyword() { return io::to_lower(next()); }
    std::int64_t integer(std::string_view field, std::int64_t min_value) {
        const std::string_view t = next();
        const auto v = io::parse_int(t);
        if (!v || *v < min_value) bad(field, "an integer >= " + std::to_string(min_value), t);
        return *v;
    }
    double number(std::string_view field, bool nonzero) {
        const std::string_view t = next();
        const auto v = io::parse_double(t);
        if (!v || !std::isfinite(*v) || (nonzero && *v == 0.0))
            bad(field, nonzero ? "a finite non-zero number" : "a finite number", t);
        return *v;
    }
    /// The position just after the current line's newline (binary data start).
    std::uint64_t after_newline() {
        const std::size_t nl = text_.find('\n', pos_);
        if (nl == std::string_view::npos) {
            if (!whole_) throw NeedMore{};
            return text_.size();
        }
        return nl + 1;
    }
    [[nodiscard]] std::uint64_t pos() const { return pos_; }

    [[noreturn]] void bad(std::string_view field, const std::string& expected, std::string_view got) const {
        std::string reason = "keyword ";
        reason.append(field)
            .append(": expected ")
            .append(expected)
            .append(", got '")
            .append(got.substr(0, 60))
            .append("'");
        throw Error(subject_, reason);
    }

private:
    [[noreturn]] void ends() const {
        throw Error(subject_, "the header ends before the scalar data (truncated file?)");
    }

    const std::string& subject_;
    std::string_view text_;
    bool whole_;
    std::size_t pos_ = 0;
};

DType parse_scalar_type(const std::string& subject, std::string_view type) {
    const std::string t = io::to_lower(type);
    if (t == "unsigned_char") return DType::u8;
    if (t == "char" || t == "signed_char") return DType::i8;
    if (t == "unsigned_short") return DType::u16;
    if (t == "short") return DType::i16;
    if (t == "unsigned_int") return DType::u32;
    if (t == "int") return DType::i32;
    if (t == "float") return DType::f32;
    if (t == "double") return DType::f64;
    std::string reason = "SCALARS type '";
    reason.append(type);
    if (t == "long" || t == "unsigned_long" || t == "vtktypeint64" || t == "vtktypeuint64" ||
        t == "vtkidtype" || t == "long_long" || t == "unsigned_long_long" || t == "bit" || t == "string" ||
        t == "utf8_string")
        reason.append("' is unsupported");
    else
        reason.append("' is unknown");
    reason.append(
        " (unsigned_char, char, unsigned_short, short, unsigned_int, int, float and double are read)");
    throw Error(subject, reason);
}

void parse_dataset(const std::string& subject, Tokens& t, VtkHeader& h) {
    for (;;) {
        const std::string k = t.keyword();
        if (k == "dimensions") {
            std::array<std::int64_t, 3> d{};
            for (auto& n : d) n = t.integer("DIMENSIONS", 1);
            h.dims = d;
        } else if (k == "spacing" || k == "aspect_ratio") {
            const char* name = k == "spacing" ? "SPACING" : "ASPECT_RATIO";
            for (int a = 0; a < 3; ++a) h.spacing[a] = t.number(name, true);
        } else if (k == "origin") {
            for (int a = 0; a < 3; ++a) h.origin[a] = t.number("ORIGIN", false);
        } else if (k == "direction") {
            std::array<double, 9> d{};
            for (auto& x : d) x = t.number("DIRECTION", false);
            h.direction = d;
        } else if (k == "point_data") {
            h.points = t.integer("POINT_DATA", 0);
            return;
        } else if (k == "cell_data") {
            throw Error(subject, "CELL_DATA is unsupported: fathom reads POINT_DATA SCALARS");
        } else if (k == "field") {
            throw Error(subject,
                        "FIELD data in the dataset are unsupported: fathom reads POINT_DATA SCALARS");
        } else {
            std::string reason = "unknown keyword '";
            reason.append(k.substr(0, 60))
                .append(
                    "' in DATASET STRUCTURED_POINTS (DIMENSIONS, SPACING, ASPECT_RATIO, ORIGIN, POINT_DATA "
                    "are read)");
            throw Error(subject, reason);
        }
    }
}

/// Parses the header from a prefix of the file; nullopt when more text is needed.
std::optional<VtkHeader> parse_header(const std::string& subject, std::string_view text, bool whole) {
    constexpr std::string_view kMagic = "# vtk datafile";
    if ((text.size() >= kMagic.size() || whole) && io::to_lower(text.substr(0, kMagic.size())) != kMagic)
        throw Error(subject, "not a legacy VTK file: the first line must be '# vtk DataFile Version x.x'");
    try {
        Tokens t(subject, text, whole);
        t.line();  // the magic
        t.line();  // the title
        VtkHeader h;
        const std::string format = t.keyword();  // line 3, after any blank lines (as vtkDataReader reads it)
        if (format == "binary")
            h.binary = true;
        else if (format != "ascii")
            throw Error(subject,
                        "after the title line: expected ASCII or BINARY, got '" + format.substr(0, 60) + "'");
        const std::string dataset = t.keyword();
        if (dataset != "dataset")
            throw Error(subject, "expected 'DATASET STRUCTURED_POINTS' after ASCII/BINARY, got '" +
                                     dataset.substr(0, 60) + "'");
        const std::string_view kind = t.next();
        if (io::to_lower(kind) != "structured_points")
            throw Error(subject, "DATASET " + std::string(kind.substr(0, 60)) +
                                     " is unsupported (only STRUCTURED_POINTS, a regular grid, is read)");
        parse_dataset(subject, t, h);
        if (!h.dims) throw Error(subject, "missing keyword DIMENSIONS before POINT_DATA");
        const std::string_view attribute = t.next();
        if (io::to_lower(attribute) != "scalars") {
            std::string reason = "POINT_DATA: the first attribute is '";
            reason.append(attribute.substr(0, 60)).append("'; only SCALARS are read (they must come first)");
            throw Error(subject, reason);
        }
        t.next();  // the array name
        h.dtype = parse_scalar_type(subject, t.next());
        std::string k = t.keyword();
        if (k != "lookup_table") {
            const auto comps = io::parse_int(k);
            if (comps != 1)
                throw Error(subject,
                            "SCALARS: " + k.substr(0, 60) +
                                " components are unsupported (1 is read; expected LOOKUP_TABLE or 1)");
            k = t.keyword();
        }
        if (k != "lookup_table") t.bad("SCALARS", "LOOKUP_TABLE", k);
        t.next();  // the table name ("default"); the table itself, if any, follows the data
        h.data_start = h.binary ? t.after_newline() : t.pos();
        return h;
    } catch (const NeedMore&) {
        return std::nullopt;
    }
}

}  // namespace

Volume read_legacy_vtk(const std::filesystem::path& path) {
    const std::string subject = path.string();
    const VtkHeader h = io::parse_growing_prefix(
        subject, path, [&](std::string_view text, bool whole) { return parse_header(subject, text, whole); });
    const io::GridShape shape{*h.dims, h.dtype, 1};
    const std::uint64_t bytes = io::grid_bytes(subject, "DIMENSIONS", shape);
    const std::uint64_t nodes = bytes / dtype_size(h.dtype);
    if (static_cast<std::uint64_t>(h.points) != nodes)
        throw Error(subject, "POINT_DATA " + std::to_string(h.points) + " does not match DIMENSIONS " +
                                 std::to_string(shape.dims[0]) + " x " + std::to_string(shape.dims[1]) +
                                 " x " + std::to_string(shape.dims[2]) + " = " + std::to_string(nodes) +
                                 " points");
    Mat3 axes = Mat3::diagonal(h.spacing);
    if (h.direction) {
        const auto& d = *h.direction;
        axes = Mat3::from_columns(Vec3{d[0], d[3], d[6]} * h.spacing.x, Vec3{d[1], d[4], d[7]} * h.spacing.y,
                                  Vec3{d[2], d[5], d[8]} * h.spacing.z);
    }

    io::DataSpec spec;
    spec.encoding = h.binary ? io::Encoding::raw : io::Encoding::ascii;
    spec.big_endian = true;  // legacy VTK binary data are big-endian
    spec.warn_extra = false;
    Volume v = io::read_grid(subject, shape, {io::DataFile{path, h.data_start, true}}, spec);
    v.set_axes(axes, subject);
    v.set_origin(h.origin);

    if (h.binary) {
        const std::uint64_t end = h.data_start + bytes;
        const std::uint64_t size = io::file_size_checked(subject, path, "file");
        const std::string tail = io::read_range(subject, path, end, 4096);
        if (size - end > tail.size() || !io::trim(tail).empty())
            warn(subject + ": " + std::to_string(size - end) +
                 " bytes after the scalars are ignored (other attributes are not read)");
    }
    return v;
}

}  // namespace fathom
