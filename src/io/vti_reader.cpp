// VTK XML ImageData reader (.vti), parsed with pugixml.
//
// <VTKFile type="ImageData" byte_order="LittleEndian|BigEndian"
//          header_type="UInt32|UInt64" compressor="vtkZLibDataCompressor">
//   <ImageData WholeExtent="x0 x1 y0 y1 z0 z1" Origin="..." Spacing="..." Direction="9 numbers">
//     <Piece Extent="..."><PointData Scalars="name"><DataArray type=... Name=... format=...>
//   </ImageData>
//   <AppendedData encoding="raw|base64"> _ ...bytes... </AppendedData>
// </VTKFile>
//
// One piece covering the WholeExtent; the PointData array named by
// Scalars, else the first; one component. Node (i, j, k) of the extent sits
// at Origin + M·(i, j, k) with column a of M = Spacing[a] · column a of the
// row-major Direction, so fathom's origin is Origin + M·(x0, y0, z0).
//
// Binary blocks (inline base64, appended raw or base64): uncompressed, one
// header integer (UInt32/UInt64 per header_type) with the byte count, then
// the bytes; zlib-compressed, the header [blocks, block size, size of a
// partial last block (0: full), compressed size of each block], then each
// block's zlib stream. Base64 is decoded group by group, so a header and data
// encoded as one stream or as two padded streams both read. Header and data
// use byte_order.
//
// The raw appended bytes are not XML: the XML parsed is the file up to the
// <AppendedData> start tag, closed there; the data are then read from the
// file after the '_' marker, at each array's offset.
#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cmath>
#include <cstring>
#include <fstream>
#include <limits>
#include <memory>
#include <optional>
#include <pugixml.hpp>
#include <string>
#include <string_view>
#include <type_traits>
#include <vector>

#include <zlib.h>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"

#include "io/io_util.h"

namespace fathom {
namespace {

struct Layout {
    bool big_endian = false;
    std::size_t header_bytes = 4;  // UInt32 or UInt64
    bool zlib = false;
};

// ================================================================ byte sources

/// The bytes of one DataArray's binary block (header, then data), in order.
class ByteSource {
public:
    ByteSource(const std::string& subject, std::string label) : subject_(subject), label_(std::move(label)) {}
    virtual ~ByteSource() = default;
    ByteSource(const ByteSource&) = delete;
    ByteSource& operator=(const ByteSource&) = delete;
    /// Exactly n bytes, or Error when the data end first.
    virtual void read(std::byte* dst, std::size_t n) = 0;
    /// An upper bound on the bytes left (to refuse impossible sizes before allocating).
    [[nodiscard]] virtual std::uint64_t bound() const = 0;

protected:
    [[noreturn]] void ends(std::uint64_t need) const {
        std::string reason = label_;
        reason.append(" ends early: ")
            .append(std::to_string(need))
            .append(" more bytes are needed, at most ")
            .append(std::to_string(bound()))
            .append(" remain (truncated file?)");
        throw Error(subject_, reason);
    }
    const std::string& subject_;
    std::string label_;
};

/// Raw bytes of a file from an offset on.
class RawFileSource final : public ByteSource {
public:
    RawFileSource(const std::string& subject, std::string label, const std::filesystem::path& file,
                  std::uint64_t offset, std::uint64_t size)
        : ByteSource(subject, std::move(label)), in_(file, std::ios::binary), left_(size - offset) {
        if (!in_) throw Error(subject_, "cannot open the file");
        in_.seekg(static_cast<std::streamoff>(offset));
        if (!in_) throw Error(subject_, "cannot seek to byte " + std::to_string(offset));
    }
    void read(std::byte* dst, std::size_t n) override {
        if (n > left_) ends(n);
        std::size_t done = 0;
        while (done < n) {
            const std::size_t chunk = std::min<std::size_t>(n - done, std::size_t{1} << 30);
            in_.read(reinterpret_cast<char*>(dst) + done, static_cast<std::streamsize>(chunk));
            const auto got = static_cast<std::size_t>(in_.gcount());
            if (got != chunk) throw Error(subject_, label_ + ": read error");
            done += got;
        }
        left_ -= n;
    }
    [[nodiscard]] std::uint64_t bound() const override { return left_; }

private:
    std::ifstream in_;
    std::uint64_t left_;
};

constexpr std::array<signed char, 256> make_base64_table() {
    std::array<signed char, 256> t{};
    for (auto& v : t) v = -1;
    constexpr std::string_view kAlphabet = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    for (std::size_t i = 0; i < kAlphabet.size(); ++i)
        t[static_cast<unsigned char>(kAlphabet[i])] = static_cast<signed char>(i);
    return t;
}
constexpr auto kBase64 = make_base64_table();

/// Base64 text (in memory, or in a file from an offset on), decoded in groups
/// of 4 characters; whitespace is skipped and '=' padding ends a group, not
/// the stream (so separately encoded header and data follow each other).
class Base64Source final : public ByteSource {
public:
    Base64Source(const std::string& subject, std::string label, std::string_view text)
        : ByteSource(subject, std::move(label)), buf_(text) {}
    Base64Source(const std::string& subject, std::string label, const std::filesystem::path& file,
                 std::uint64_t offset, std::uint64_t size)
        : ByteSource(subject, std::move(label)),
          file_(std::make_unique<std::ifstream>(file, std::ios::binary)),
          file_left_(size - offset) {
        if (!*file_) throw Error(subject_, "cannot open the file");
        file_->seekg(static_cast<std::streamoff>(offset));
        if (!*file_) throw Error(subject_, "cannot seek to byte " + std::to_string(offset));
    }

    void read(std::byte* dst, std::size_t n) override {
        std::size_t done = 0;
        while (done < n) {
            if (pending_pos_ == pending_n_) decode_group(n - done);
            const std::size_t k = std::min<std::size_t>(pending_n_ - pending_pos_, n - done);
            std::memcpy(dst + done, pending_.data() + pending_pos_, k);
            pending_pos_ += k;
            done += k;
        }
    }
    [[nodiscard]] std::uint64_t bound() const override {
        return (file_left_ + (buf_.size() - pos_)) / 4 * 3 + 3 + (pending_n_ - pending_pos_);
    }

private:
    /// The next non-whitespace character, or -1 at the end of the text.
    int next_char() {
        for (;;) {
            if (pos_ == buf_.size() && !refill()) return -1;
            const auto c = static_cast<unsigned char>(buf_[pos_++]);
            if (!std::isspace(c)) return c;
        }
    }
    bool refill() {
        if (!file_ || file_left_ == 0) return false;
        chunk_.resize(static_cast<std::size_t>(std::min<std::uint64_t>(file_left_, std::size_t{1} << 18)));
        file_->read(chunk_.data(), static_cast<std::streamsize>(chunk_.size()));
        if (static_cast<std::size_t>(file_->gcount()) != chunk_.size())
            throw Error(subject_, label_ + ": read error");
        file_left_ -= chunk_.size();
        buf_ = chunk_;
        pos_ = 0;
        return true;
    }
    void decode_group(std::size_t need) {
        std::array<int, 4> c{};
        for (std::size_t i = 0; i < 4; ++i) {
            c[i] = next_char();
            if (c[i] < 0) {
                if (i == 0) ends(need);
                throw Error(subject_, label_ + ": the base64 text ends inside a group of 4 characters");
            }
        }
        std::uint32_t bits = 0;
        std::size_t bytes = 3;
        for (std::size_t i = 0; i < 4; ++i) {
            const int v = kBase64[static_cast<std::size_t>(c[i])];
            const bool pad = c[i] == '=' && i >= 2 && (i == 3 || c[3] == '=');
            if (v < 0 && !pad) {
                std::string reason = label_;
                reason.append(": invalid base64 character ");
                if (std::isprint(c[i]))
                    reason.append("'").append(1, static_cast<char>(c[i])).append("'");
                else
                    reason.append("code ").append(std::to_string(c[i]));
                reason.append(" (corrupt data)");
                throw Error(subject_, reason);
            }
            if (pad) bytes = std::min(bytes, i - 1);
            bits = (bits << 6) | static_cast<std::uint32_t>(pad ? 0 : v);
        }
        pending_ = {std::byte(bits >> 16), std::byte((bits >> 8) & 0xffu), std::byte(bits & 0xffu)};
        pending_n_ = bytes;
        pending_pos_ = 0;
    }

    std::string_view buf_;
    std::size_t pos_ = 0;
    std::unique_ptr<std::ifstream> file_;
    std::uint64_t file_left_ = 0;
    std::string chunk_;
    std::array<std::byte, 3> pending_{};
    std::size_t pending_n_ = 0, pending_pos_ = 0;
};

// ================================================================ decoding

std::uint64_t read_header_int(ByteSource& src, const Layout& f) {
    std::array<std::byte, 8> b{};
    src.read(b.data(), f.header_bytes);
    if (f.big_endian != (std::endian::native == std::endian::big))
        std::reverse(b.begin(), b.begin() + static_cast<std::ptrdiff_t>(f.header_bytes));
    if (f.header_bytes == 4) {
        std::uint32_t v = 0;
        std::memcpy(&v, b.data(), 4);
        return v;
    }
    std::uint64_t v = 0;
    std::memcpy(&v, b.data(), 8);
    return v;
}

/// A binary block: the header checked against the grid, then the data.
Volume read_binary(const std::string& subject, const std::string& label, ByteSource& src, const Layout& f,
                   const io::GridShape& shape, std::uint64_t need) {
    const auto fail = [&](const std::string& what) {
        std::string reason = label;
        reason.append(": ").append(what);
        return Error(subject, reason);
    };
    if (!f.zlib) {
        const std::uint64_t n = read_header_int(src, f);
        if (n != need)
            throw fail("its header says " + std::to_string(n) + " bytes of data, the WholeExtent needs " +
                       std::to_string(need));
        if (n > src.bound())
            throw fail("holds at most " + std::to_string(src.bound()) + " bytes of data, expected " +
                       std::to_string(n) + " (truncated file?)");
        Volume v(shape.dims, shape.dtype, 1);
        src.read(v.bytes(), v.size_bytes());
        return v;
    }
    const std::uint64_t blocks = read_header_int(src, f);
    if (blocks > src.bound() / f.header_bytes)
        throw fail("its compression header claims " + std::to_string(blocks) +
                   " blocks, more than the data can hold (corrupt or truncated)");
    const std::uint64_t block_size = read_header_int(src, f);
    const std::uint64_t last_size = read_header_int(src, f);
    std::vector<std::uint64_t> sizes(static_cast<std::size_t>(blocks));
    for (auto& s : sizes) s = read_header_int(src, f);
    const std::uint64_t last = last_size == 0 ? block_size : last_size;
    const auto kMax = std::numeric_limits<std::uint64_t>::max();
    if (last_size > block_size || (blocks > 1 && block_size > (kMax - last) / (blocks - 1)) ||
        (blocks == 0 ? 0 : (blocks - 1) * block_size + last) != need)
        throw fail("its compression header (" + std::to_string(blocks) + " blocks of " +
                   std::to_string(block_size) + " bytes, last block " + std::to_string(last_size) +
                   ") does not describe the " + std::to_string(need) + " bytes the WholeExtent needs");
    std::uint64_t total = 0;
    for (auto s : sizes) {
        if (s > kMax - total) throw fail("the compressed block sizes overflow (corrupt header)");
        total += s;
    }
    if (total > src.bound())
        throw fail("its blocks hold " + std::to_string(total) + " compressed bytes, at most " +
                   std::to_string(src.bound()) + " remain (truncated file?)");
    if (need / 1032 > total + 64 * blocks)  // deflate expands at most 1032:1
        throw fail(std::to_string(total) + " compressed bytes cannot expand to " + std::to_string(need));

    Volume v(shape.dims, shape.dtype, 1);
    std::vector<std::byte> code;
    std::uint64_t at = 0;
    for (std::size_t b = 0; b < sizes.size(); ++b) {
        code.resize(static_cast<std::size_t>(sizes[b]));
        src.read(code.data(), code.size());
        const std::uint64_t want = b + 1 == sizes.size() ? last : block_size;
        auto got = static_cast<uLongf>(want);
        const int rc =
            uncompress(reinterpret_cast<Bytef*>(v.bytes() + at), &got,
                       reinterpret_cast<const Bytef*>(code.data()), static_cast<uLong>(code.size()));
        if (rc != Z_OK || got != want) {
            std::string what = "corrupt zlib data in block " + std::to_string(b) + " of " +
                               std::to_string(sizes.size()) + ": ";
            what.append(rc != Z_OK ? zError(rc)
                                   : "it expands to " + std::to_string(got) + " bytes, expected " +
                                         std::to_string(want));
            throw fail(what);
        }
        at += want;
    }
    return v;
}

template <class T>
bool parse_value(std::string_view token, T& out) {
    if constexpr (std::is_floating_point_v<T>) {
        const auto v = io::parse_double(token);
        if (!v || (std::isfinite(*v) && std::abs(*v) > static_cast<double>(std::numeric_limits<T>::max())))
            return false;
        out = static_cast<T>(*v);  // NaN and Inf pass: check_finite names the sample
    } else {
        const auto v = io::parse_int(token);
        if (!v || *v < static_cast<std::int64_t>(std::numeric_limits<T>::min()) ||
            *v > static_cast<std::int64_t>(std::numeric_limits<T>::max()))
            return false;
        out = static_cast<T>(*v);
    }
    return true;
}

Volume read_ascii(const std::string& subject, const std::string& label, std::string_view text,
                  const io::GridShape& shape, std::uint64_t nodes) {
    if (text.size() < nodes)
        throw Error(subject, label + " holds " + std::to_string(text.size()) + " characters, too few for " +
                                 std::to_string(nodes) + " values");
    Volume v(shape.dims, shape.dtype, 1);
    visit_dtype(shape.dtype, [&]<class T>(T*) {
        T* out = v.data<T>();
        std::uint64_t n = 0;
        std::size_t i = 0;
        const auto space = [&](std::size_t k) {
            return std::isspace(static_cast<unsigned char>(text[k])) != 0;
        };
        for (;;) {
            while (i < text.size() && space(i)) ++i;
            if (i == text.size()) break;
            const std::size_t b = i;
            while (i < text.size() && !space(i)) ++i;
            const std::string_view token = text.substr(b, i - b);
            if (n == nodes)
                throw Error(subject, label + " holds more than the " + std::to_string(nodes) +
                                         " values the WholeExtent needs");
            if (!parse_value(token, out[n])) {
                std::string reason = label;
                reason.append(": value ")
                    .append(std::to_string(n))
                    .append(" '")
                    .append(token.substr(0, 40))
                    .append("' is not a valid ")
                    .append(dtype_name(shape.dtype));
                throw Error(subject, reason);
            }
            ++n;
        }
        if (n < nodes)
            throw Error(subject,
                        label + " holds " + std::to_string(n) + " values, expected " + std::to_string(nodes));
    });
    return v;
}

// ================================================================ the file

DType parse_array_type(const std::string& subject, const std::string& label, std::string_view type) {
    static constexpr std::array<std::pair<std::string_view, DType>, 8> kTypes{{
        {"Int8", DType::i8},
        {"UInt8", DType::u8},
        {"Int16", DType::i16},
        {"UInt16", DType::u16},
        {"Int32", DType::i32},
        {"UInt32", DType::u32},
        {"Float32", DType::f32},
        {"Float64", DType::f64},
    }};
    for (const auto& [name, t] : kTypes)
        if (name == type) return t;
    std::string reason = label;
    reason.append(": type '").append(type.substr(0, 40));
    reason.append(type == "Int64" || type == "UInt64" || type == "String" || type == "Bit"
                      ? "' is unsupported"
                      : "' is unknown");
    reason.append(" (Int8, UInt8, Int16, UInt16, Int32, UInt32, Float32 and Float64 are read)");
    throw Error(subject, reason);
}

class VtiReader {
public:
    explicit VtiReader(const std::filesystem::path& path)
        : path_(path), subject_(path.string()), size_(io::file_size_checked(subject_, path, "file")) {}

    Volume read() {
        load_xml();
        const pugi::xml_node root = doc_.child("VTKFile");
        if (!root) throw Error(subject_, "not a VTK XML file: there is no <VTKFile> element");
        const std::string_view type = root.attribute("type").value();
        if (type != "ImageData")
            throw Error(subject_, "VTKFile type '" + std::string(type.substr(0, 40)) +
                                      "' is unsupported (only ImageData, .vti, is read)");
        const Layout layout = parse_layout(root);
        const pugi::xml_node image = root.child("ImageData");
        if (!image) throw Error(subject_, "there is no <ImageData> element");
        const auto extent = io::field_ints(subject_, "WholeExtent", require(image, "WholeExtent"), 6,
                                           -(std::int64_t{1} << 40));
        io::GridShape shape;
        for (std::size_t a = 0; a < 3; ++a) {
            if (extent[2 * a + 1] < extent[2 * a] || extent[2 * a + 1] > (std::int64_t{1} << 40))
                throw Error(subject_,
                            "attribute 'WholeExtent': expected x0 x1 y0 y1 z0 z1 with each max >= min, "
                            "got '" +
                                std::string(require(image, "WholeExtent")) + "'");
            shape.dims[a] = extent[2 * a + 1] - extent[2 * a] + 1;
        }
        const pugi::xml_node array = find_array(image, extent);
        const std::string label = "DataArray '" + std::string(array.attribute("Name").value()) + "'";
        shape.dtype = parse_array_type(subject_, label, array.attribute("type").value());
        if (const auto c = array.attribute("NumberOfComponents"); c && io::parse_int(c.value()) != 1)
            throw Error(subject_, label + ": NumberOfComponents " + std::string(c.value()) +
                                      " is unsupported (1 is read)");
        const std::uint64_t bytes = io::grid_bytes(subject_, "WholeExtent", shape);
        const Mat3 axes = parse_axes(image);
        const Vec3 origin = parse_vec(image, "Origin", {0, 0, 0}, false) +
                            axes * Vec3{static_cast<double>(extent[0]), static_cast<double>(extent[2]),
                                        static_cast<double>(extent[4])};

        Volume v = read_array(array, label, layout, shape, bytes);
        v.set_axes(axes, subject_);
        v.set_origin(origin);
        io::check_finite(subject_, v);
        return v;
    }

private:
    void load_xml();
    Layout parse_layout(const pugi::xml_node& root) const;
    pugi::xml_node find_array(const pugi::xml_node& image, const std::vector<std::int64_t>& extent) const;
    Mat3 parse_axes(const pugi::xml_node& image) const;
    Vec3 parse_vec(const pugi::xml_node& node, const char* name, const Vec3& fallback, bool nonzero) const;
    Volume read_array(const pugi::xml_node& array, const std::string& label, const Layout& layout,
                      const io::GridShape& shape, std::uint64_t bytes) const;

    std::string_view require(const pugi::xml_node& node, const char* name) const {
        const auto a = node.attribute(name);
        if (!a) {
            std::string reason = "<";
            reason.append(node.name()).append("> has no attribute '").append(name).append("'");
            throw Error(subject_, reason);
        }
        return a.value();
    }

    std::filesystem::path path_;
    std::string subject_;
    std::uint64_t size_;
    std::string xml_;  // what pugixml parses in place
    pugi::xml_document doc_;
    std::optional<std::uint64_t> appended_;  // the file offset just after the '_' marker
};

void VtiReader::load_xml() {
    // Look for <AppendedData> in growing prefixes; without it the whole file is XML.
    constexpr std::string_view kTag = "<AppendedData";
    std::size_t at = std::string::npos, tag_end = std::string::npos;
    for (std::uint64_t n : {std::uint64_t{1} << 16, std::uint64_t{1} << 20, std::uint64_t{1} << 24, size_}) {
        if (size_ > std::numeric_limits<std::size_t>::max() / 2)
            throw Error(subject_, "the file is too large to read as XML");
        xml_ = io::read_prefix(subject_, path_, static_cast<std::size_t>(std::min(n, size_)));
        at = xml_.find(kTag);
        if (at != std::string::npos) tag_end = xml_.find('>', at);
        if (tag_end != std::string::npos || xml_.size() >= size_) break;
    }
    if (at != std::string::npos) {
        if (tag_end == std::string::npos) throw Error(subject_, "the <AppendedData> tag does not end");
        const bool empty = xml_[tag_end - 1] == '/';
        if (!empty) {
            // the '_' marker follows the start tag after optional whitespace
            const std::string after = io::read_range(subject_, path_, tag_end + 1, 4096);
            const std::size_t mark = after.find_first_not_of(" \t\r\n");
            if (mark == std::string::npos || after[mark] != '_')
                throw Error(subject_, "<AppendedData>: expected the '_' marker before the data");
            appended_ = tag_end + 1 + mark + 1;
        }
        xml_.resize(tag_end + 1);
        xml_.append(empty ? "</VTKFile>" : "</AppendedData></VTKFile>");
    }
    const pugi::xml_parse_result r =
        doc_.load_buffer_inplace(xml_.data(), xml_.size(), pugi::parse_default, pugi::encoding_utf8);
    if (!r) {
        std::string reason = "XML error at byte ";
        reason.append(std::to_string(r.offset)).append(": ").append(r.description());
        throw Error(subject_, reason);
    }
}

Layout VtiReader::parse_layout(const pugi::xml_node& root) const {
    Layout f;
    const std::string_view order = root.attribute("byte_order").as_string("LittleEndian");
    if (order == "BigEndian")
        f.big_endian = true;
    else if (order != "LittleEndian")
        throw Error(subject_, "attribute 'byte_order': expected LittleEndian or BigEndian, got '" +
                                  std::string(order.substr(0, 40)) + "'");
    const std::string_view header = root.attribute("header_type").as_string("UInt32");
    if (header == "UInt64")
        f.header_bytes = 8;
    else if (header != "UInt32")
        throw Error(subject_, "attribute 'header_type': expected UInt32 or UInt64, got '" +
                                  std::string(header.substr(0, 40)) + "'");
    const std::string_view compressor = root.attribute("compressor").value();
    if (compressor == "vtkZLibDataCompressor")
        f.zlib = true;
    else if (!compressor.empty())
        throw Error(subject_, "compressor '" + std::string(compressor.substr(0, 60)) +
                                  "' is unsupported (vtkZLibDataCompressor or none is read)");
    return f;
}

pugi::xml_node VtiReader::find_array(const pugi::xml_node& image,
                                     const std::vector<std::int64_t>& extent) const {
    const auto pieces = std::distance(image.children("Piece").begin(), image.children("Piece").end());
    if (pieces != 1)
        throw Error(subject_, "<ImageData> holds " + std::to_string(pieces) + " pieces; one piece is read");
    const pugi::xml_node piece = image.child("Piece");
    if (const auto e = piece.attribute("Extent")) {
        const auto pe =
            io::field_ints(subject_, "Extent", e.value(), 6, std::numeric_limits<std::int64_t>::min());
        if (pe != extent)
            throw Error(subject_, "the piece's Extent '" + std::string(e.value()) +
                                      "' differs from the WholeExtent (partial pieces are unsupported)");
    }
    const pugi::xml_node point_data = piece.child("PointData");
    const pugi::xml_node first = point_data.child("DataArray");
    if (!first) throw Error(subject_, "the piece has no PointData DataArray (cell data are not read)");
    const std::string_view scalars = point_data.attribute("Scalars").value();
    if (!scalars.empty()) {
        for (const auto& a : point_data.children("DataArray"))
            if (scalars == a.attribute("Name").value()) return a;
        warn(subject_ + ": PointData Scalars='" + std::string(scalars) +
             "' names no array; reading the first, '" + first.attribute("Name").value() + "'");
    } else if (first.next_sibling("DataArray")) {
        warn(subject_ + ": PointData holds several arrays and names no Scalars; reading the first, '" +
             first.attribute("Name").value() + "'");
    }
    return first;
}

Vec3 VtiReader::parse_vec(const pugi::xml_node& node, const char* name, const Vec3& fallback,
                          bool nonzero) const {
    const auto a = node.attribute(name);
    if (!a) return fallback;
    const auto v = io::field_doubles(subject_, name, a.value(), 3);
    for (double x : v)
        if (!std::isfinite(x) || (nonzero && x == 0.0)) {
            std::string reason = "attribute '";
            reason.append(name)
                .append(nonzero ? "': expected 3 finite non-zero numbers, got '"
                                : "': expected 3 finite numbers, got '")
                .append(a.value())
                .append("'");
            throw Error(subject_, reason);
        }
    return {v[0], v[1], v[2]};
}

Mat3 VtiReader::parse_axes(const pugi::xml_node& image) const {
    const Vec3 s = parse_vec(image, "Spacing", {1, 1, 1}, true);
    const auto dir = image.attribute("Direction");
    if (!dir) return Mat3::diagonal(s);
    const auto d = io::field_doubles(subject_, "Direction", dir.value(), 9);  // row-major
    const Mat3 m = Mat3::from_columns(Vec3{d[0], d[3], d[6]} * s.x, Vec3{d[1], d[4], d[7]} * s.y,
                                      Vec3{d[2], d[5], d[8]} * s.z);
    if (!std::isfinite(m.determinant()) || m.determinant() == 0.0)
        throw Error(subject_, "attribute 'Direction': the matrix is singular or not finite");
    return m;
}

Volume VtiReader::read_array(const pugi::xml_node& array, const std::string& label, const Layout& layout,
                             const io::GridShape& shape, std::uint64_t bytes) const {
    const std::string_view format = array.attribute("format").value();
    const std::uint64_t nodes = bytes / dtype_size(shape.dtype);
    Volume v;
    if (format == "ascii") {
        return read_ascii(subject_, label, array.text().get(), shape, nodes);
    } else if (format == "binary") {
        Base64Source src(subject_, label, array.text().get());
        v = read_binary(subject_, label, src, layout, shape, bytes);
    } else if (format == "appended") {
        const auto appended = array.root().child("VTKFile").child("AppendedData");
        if (!appended || !appended_)
            throw Error(subject_, label + " is appended, but the file has no <AppendedData> with data");
        const auto offset = io::parse_int(array.attribute("offset").value());
        if (!offset || *offset < 0)
            throw Error(subject_, label + ": attribute 'offset': expected a non-negative integer, got '" +
                                      std::string(array.attribute("offset").value()) + "'");
        const auto at = *appended_ + static_cast<std::uint64_t>(*offset);
        if (static_cast<std::uint64_t>(*offset) > size_ - *appended_)
            throw Error(subject_, label + ": offset " + std::to_string(*offset) +
                                      " lies past the end of the file (truncated file?)");
        const std::string_view encoding = appended.attribute("encoding").as_string("raw");
        if (encoding == "raw") {
            RawFileSource src(subject_, label, path_, at, size_);
            v = read_binary(subject_, label, src, layout, shape, bytes);
        } else if (encoding == "base64") {
            Base64Source src(subject_, label, path_, at, size_);
            v = read_binary(subject_, label, src, layout, shape, bytes);
        } else {
            throw Error(subject_, "<AppendedData> encoding '" + std::string(encoding.substr(0, 40)) +
                                      "' is unknown (raw or base64)");
        }
    } else {
        throw Error(subject_, label + ": format '" + std::string(format.substr(0, 40)) +
                                  "' is unknown (ascii, binary or appended)");
    }
    if (layout.big_endian != (std::endian::native == std::endian::big))
        io::swap_bytes(std::span<std::byte>(v.bytes(), v.size_bytes()), dtype_size(shape.dtype));
    return v;
}

}  // namespace

Volume read_vti(const std::filesystem::path& path) {
    return VtiReader(path).read();
}

}  // namespace fathom
