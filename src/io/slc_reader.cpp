// SLC reader: the VolVis slice format, as VTK's vtkSLCReader reads it.
//
// Layout (text fields are whitespace-separated decimal numbers, read like
// fscanf "%d"/"%lf"):
//   magic (11111)  nx ny nz  bits_per_voxel  sx sy sz
//   unit_type  data_origin  data_modification  compression
//   icon_width icon_height X  then 3 · w · h icon bytes (red, green, blue planes)
//   per slice (z = 0 .. nz-1):
//     compression 0: nx · ny raw bytes (no size field, as vtkSLCReader reads them)
//     compression 1: "SIZE X" then SIZE bytes of 8-bit run-length code
// The run-length code is a sequence of runs: a byte c with n = c & 0x7f;
// n = 0 ends the slice; c & 0x80 copies the next n bytes, otherwise the next
// byte is repeated n times. Samples are uint8, x fastest; spacing from the
// header, origin (0, 0, 0) (data_origin names how the data were made, not a
// position). Bits other than 8 and unknown compressions are refused.
//
// The short slice quirk: some files (embryo.slc) hold slices whose runs end
// before the slice is full (each embryo slice decodes to 65535 of 65536
// bytes). vtkSLCReader decodes into an uninitialised buffer and copies the
// whole plane, so the missing samples are left unset there; fathom sets them
// to 0 (the value a fresh allocation holds in practice) and warns once per
// file. A slice short by more than one row (nx samples), or one whose runs
// overflow the slice or the size field, is corrupt: an error.
#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
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

constexpr int kMagic = 11111;

struct SlcHeader {
    std::array<std::int64_t, 3> dims{0, 0, 0};
    Vec3 spacing{1, 1, 1};
    std::int64_t compression = 0;
    std::uint64_t data_start = 0;  // the first slice, after the icon
};

/// A cursor over the header text: whitespace-separated numbers, as fscanf reads them.
class HeaderCursor {
public:
    HeaderCursor(const std::string& subject, std::string_view text, bool whole)
        : subject_(subject), text_(text), whole_(whole) {}

    /// An integer, >= min_value when given.
    std::int64_t integer(const char* field, std::optional<std::int64_t> min_value = std::nullopt) {
        const std::string_view t = token(field);
        const auto v = io::parse_int(t);
        if (!v || (min_value && *v < *min_value)) {
            std::string reason = "header field '";
            reason.append(field).append("': expected an integer");
            if (min_value) reason.append(" >= ").append(std::to_string(*min_value));
            reason.append(", got '").append(t).append("'");
            throw Error(subject_, reason);
        }
        return *v;
    }
    double number(const char* field) {
        const std::string_view t = token(field);
        const auto v = io::parse_double(t);
        if (!v || !std::isfinite(*v) || *v == 0.0)
            throw Error(subject_, "header field '" + std::string(field) +
                                      "': expected a finite non-zero number, got '" + std::string(t) + "'");
        return *v;
    }
    /// Skips whitespace and one 'X' (the icon's "W H X" marker).
    void marker(const char* field) {
        skip_space();
        if (pos_ >= text_.size()) ends(field);
        if (text_[pos_] != 'X')
            throw Error(subject_, "header field '" + std::string(field) + "': expected 'X', got '" +
                                      std::string(text_.substr(pos_, 1)) + "'");
        ++pos_;
    }
    [[nodiscard]] std::size_t pos() const { return pos_; }

private:
    void skip_space() {
        while (pos_ < text_.size() && std::isspace(static_cast<unsigned char>(text_[pos_]))) ++pos_;
    }
    std::string_view token(const char* field) {
        skip_space();
        const std::size_t b = pos_;
        while (pos_ < text_.size() && pos_ - b < 64 &&
               !std::isspace(static_cast<unsigned char>(text_[pos_])) && text_[pos_] != 'X')
            ++pos_;
        if (pos_ == b || (pos_ == text_.size() && !whole_)) ends(field);
        return text_.substr(b, pos_ - b);
    }
    [[noreturn]] void ends(const char* field) const {
        throw Error(subject_, "the header ends before field '" + std::string(field) + "' (truncated file?)");
    }

    const std::string& subject_;
    std::string_view text_;
    bool whole_;
    std::size_t pos_ = 0;
};

SlcHeader parse_header(const std::string& subject, const std::filesystem::path& path, std::uint64_t size) {
    const std::string text = io::read_prefix(subject, path, 4096);
    HeaderCursor c(subject, text, text.size() == size);
    const auto first = io::split_ws(std::string_view(text).substr(0, 64));
    if (first.empty() || io::parse_int(first[0]) != kMagic)
        throw Error(subject, "not an SLC file: it must start with the magic number 11111");
    c.integer("magic");
    SlcHeader h;
    const char* dim_names[3] = {"x size", "y size", "z size"};
    for (int a = 0; a < 3; ++a) h.dims[static_cast<std::size_t>(a)] = c.integer(dim_names[a], 1);
    const std::int64_t bits = c.integer("bits per voxel", 0);
    if (bits != 8)
        throw Error(subject, "header field 'bits per voxel': " + std::to_string(bits) +
                                 "-bit SLC data are unsupported (8 bits are read)");
    h.spacing.x = c.number("x spacing");
    h.spacing.y = c.number("y spacing");
    h.spacing.z = c.number("z spacing");
    c.integer("unit type");
    c.integer("data origin");
    c.integer("data modification");
    h.compression = c.integer("compression");
    if (h.compression != 0 && h.compression != 1)
        throw Error(subject, "header field 'compression': unknown SLC compression " +
                                 std::to_string(h.compression) + " (0 = none, 1 = run-length)");
    const std::int64_t icon_w = c.integer("icon width", 0);
    const std::int64_t icon_h = c.integer("icon height", 0);
    c.marker("icon size");
    const std::uint64_t start = c.pos();
    constexpr std::int64_t kMaxIconSide = std::int64_t{1} << 20;
    if (icon_w > kMaxIconSide || icon_h > kMaxIconSide ||
        3 * static_cast<std::uint64_t>(icon_w) * static_cast<std::uint64_t>(icon_h) > size - start)
        throw Error(subject, "the icon (" + std::to_string(icon_w) + " x " + std::to_string(icon_h) +
                                 ", 3 planes) does not fit in the file's " + std::to_string(size) +
                                 " bytes (truncated file?)");
    h.data_start = start + 3 * static_cast<std::uint64_t>(icon_w) * static_cast<std::uint64_t>(icon_h);
    return h;
}

/// Reads the slices from an open file stream, with clear errors at its end.
class SliceStream {
public:
    SliceStream(const std::string& subject, const std::filesystem::path& path, std::uint64_t start,
                std::uint64_t size)
        : subject_(subject), in_(path, std::ios::binary), pos_(start), size_(size) {
        if (!in_) throw Error(subject_, "cannot open the file");
        in_.seekg(static_cast<std::streamoff>(start));
        if (!in_) throw Error(subject_, "cannot seek to byte " + std::to_string(start));
    }
    [[nodiscard]] std::uint64_t left() const { return size_ - pos_; }
    [[nodiscard]] std::uint64_t pos() const { return pos_; }

    void read(void* dst, std::size_t n, std::int64_t slice) {
        if (n > left())
            throw Error(subject_, "the file ends in slice " + std::to_string(slice) + ": it needs " +
                                      std::to_string(n) + " more bytes from byte " + std::to_string(pos_) +
                                      ", the file holds " + std::to_string(left()) + " (truncated file)");
        in_.read(static_cast<char*>(dst), static_cast<std::streamsize>(n));
        if (static_cast<std::size_t>(in_.gcount()) != n)
            throw Error(subject_, "read error in slice " + std::to_string(slice));
        pos_ += n;
    }

    /// "SIZE X" before a run-length coded slice (whitespace around SIZE is skipped).
    std::uint64_t slice_size(std::int64_t slice) {
        int c = next(slice);
        while (std::isspace(c)) c = next(slice);
        std::uint64_t v = 0;
        int digits = 0;
        for (; std::isdigit(c) && digits < 19; c = next(slice), ++digits)
            v = v * 10 + static_cast<unsigned>(c - '0');
        while (std::isspace(c)) c = next(slice);
        if (digits == 0 || c != 'X')
            throw Error(subject_, "slice " + std::to_string(slice) + " at byte " + std::to_string(pos_ - 1) +
                                      ": expected its size as 'N X' (corrupt file)");
        return v;
    }

private:
    int next(std::int64_t slice) {
        if (pos_ >= size_)
            throw Error(subject_,
                        "the file ends before slice " + std::to_string(slice) + " (truncated file)");
        const int c = in_.get();
        if (c == std::char_traits<char>::eof())
            throw Error(subject_, "read error before slice " + std::to_string(slice));
        ++pos_;
        return c;
    }

    const std::string& subject_;
    std::ifstream in_;
    std::uint64_t pos_;
    std::uint64_t size_;
};

/// Decodes one slice's run-length code into `out`; returns the number of
/// samples decoded (at most out.size()). Errors for runs that leave the code
/// or overflow the slice.
std::size_t decode_rle(const std::string& subject, std::int64_t slice, const std::vector<unsigned char>& code,
                       std::uint8_t* out, std::size_t plane) {
    std::size_t i = 0, n = 0;
    while (i < code.size()) {
        const unsigned char c = code[i++];
        const std::size_t run = c & 0x7fu;
        if (run == 0) break;  // the end of the slice
        const bool literal = (c & 0x80u) != 0;
        if (literal ? run > code.size() - i : i >= code.size())
            throw Error(subject, "slice " + std::to_string(slice) + ": a run at byte " +
                                     std::to_string(i - 1) + " goes past the slice's " +
                                     std::to_string(code.size()) +
                                     " bytes of run-length code (corrupt data)");
        if (run > plane - n)
            throw Error(subject, "slice " + std::to_string(slice) + " decodes to more than its " +
                                     std::to_string(plane) + " samples (corrupt run-length data)");
        if (literal) {
            std::memcpy(out + n, code.data() + i, run);
            i += run;
        } else {
            std::memset(out + n, code[i++], run);
        }
        n += run;
    }
    return n;
}

/// Fewest bytes of run-length code that decode to n samples (127 per 2 bytes).
std::uint64_t min_code_bytes(std::uint64_t n) {
    return 2 * ((n + 126) / 127);
}

}  // namespace

Volume read_slc(const std::filesystem::path& path) {
    const std::string subject = path.string();
    const std::uint64_t size = io::file_size_checked(subject, path, "file");
    const SlcHeader h = parse_header(subject, path, size);
    const io::GridShape shape{h.dims, DType::u8, 1};
    io::grid_bytes(subject, "dimensions", shape);
    const auto nx = static_cast<std::uint64_t>(h.dims[0]);
    const auto plane = nx * static_cast<std::uint64_t>(h.dims[1]);
    const auto nz = static_cast<std::uint64_t>(h.dims[2]);

    // refuse sizes the file cannot hold before allocating
    const std::uint64_t left = size - h.data_start;
    const std::uint64_t per_slice = h.compression == 0 ? plane : 2 + min_code_bytes(plane - nx);
    if (per_slice > left / nz)
        throw Error(subject, "the file holds " + std::to_string(left) +
                                 " bytes after the header, too few for " + std::to_string(nz) +
                                 " slices of " + std::to_string(nx) + " x " + std::to_string(h.dims[1]) +
                                 (h.compression == 0 ? " samples" : " samples even run-length coded") +
                                 " (truncated file?)");

    Volume v(h.dims, DType::u8, 1);
    SliceStream in(subject, path, h.data_start, size);
    std::vector<unsigned char> code;
    std::int64_t short_slices = 0;
    std::uint64_t max_short = 0;
    for (std::uint64_t z = 0; z < nz; ++z) {
        const auto slice = static_cast<std::int64_t>(z);
        auto* out = v.data<std::uint8_t>() + z * plane;
        if (h.compression == 0) {
            in.read(out, static_cast<std::size_t>(plane), slice);
            continue;
        }
        const std::uint64_t n = in.slice_size(slice);
        if (n > in.left())
            throw Error(subject, "slice " + std::to_string(slice) + " says it holds " + std::to_string(n) +
                                     " bytes, the file has " + std::to_string(in.left()) +
                                     " left (truncated file)");
        code.resize(static_cast<std::size_t>(n));
        in.read(code.data(), code.size(), slice);
        const std::size_t got = decode_rle(subject, slice, code, out, static_cast<std::size_t>(plane));
        const std::uint64_t missing = plane - got;
        if (missing > nx)
            throw Error(subject, "slice " + std::to_string(slice) + " decodes to " + std::to_string(got) +
                                     " samples, expected " + std::to_string(plane) +
                                     " (corrupt run-length data)");
        if (missing > 0) {
            std::memset(out + got, 0, static_cast<std::size_t>(missing));
            ++short_slices;
            max_short = std::max(max_short, missing);
        }
    }
    if (short_slices > 0)
        warn(subject + ": " + std::to_string(short_slices) + " of " + std::to_string(nz) +
             " slices decode short (by up to " + std::to_string(max_short) +
             (max_short == 1 ? " sample" : " samples") +
             "); the missing samples at the end of each are set to 0");
    if (in.left() > 0) {
        const std::string tail = io::read_range(subject, path, in.pos(), 4096);
        if (in.left() > tail.size() || !io::trim(tail).empty())
            warn(subject + ": " + std::to_string(in.left()) + " bytes after the last slice are ignored");
    }
    v.set_spacing(h.spacing);
    v.set_origin({0, 0, 0});
    return v;
}

}  // namespace fathom
