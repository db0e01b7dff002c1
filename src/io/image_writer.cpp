// Image files (SPEC §6; docs/formats.md, "Image formats"): PFM, PNG and EXR
// writers through AtomicFile, and the matching readers.
#include <algorithm>
#include <array>
#include <bit>
#include <cctype>
#include <cerrno>
#include <charconv>
#include <cmath>
#include <csetjmp>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <exception>
#include <fstream>
#include <memory>
#include <string>
#include <string_view>
#include <system_error>
#include <vector>

#include <Imath/ImathBox.h>
#include <Imath/ImathVec.h>
#include <OpenEXR/ImfChannelList.h>
#include <OpenEXR/ImfFrameBuffer.h>
#include <OpenEXR/ImfHeader.h>
#include <OpenEXR/ImfInputFile.h>
#include <OpenEXR/ImfOutputFile.h>
#include <png.h>

#include "fathom/error.h"
#include "fathom/io.h"

#include "io/atomic_file.h"
#include "io/srgb.h"

namespace fathom {
namespace {

namespace fs = std::filesystem;

/// Readers refuse images of more pixels than this (checked before allocating).
constexpr std::int64_t kMaxPixels = std::int64_t{1} << 28;

[[noreturn]] void fail(const fs::path& path, const std::string& reason) {
    throw Error(path.string(), reason);
}

std::string lower_extension(const fs::path& path) {
    std::string ext = path.extension().string();
    for (char& ch : ext) ch = static_cast<char>(std::tolower(static_cast<unsigned char>(ch)));
    return ext;
}

std::size_t pixel_count(const Image& image) {
    return static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height);
}

void check_writable(const fs::path& path, const Image& image) {
    if (image.width <= 0 || image.height <= 0)
        fail(path, "cannot write an empty image (" + std::to_string(image.width) + "x" +
                       std::to_string(image.height) + ")");
    if (image.rgba.size() != pixel_count(image) * 4)
        fail(path, "image buffer size does not match its width and height");
}

void check_size(const fs::path& path, std::int64_t width, std::int64_t height) {
    if (width <= 0 || height <= 0 || width > kMaxPixels || height > kMaxPixels || width * height > kMaxPixels)
        fail(path, "unsupported image size " + std::to_string(width) + "x" + std::to_string(height) +
                       " (at most 2^28 pixels)");
}

// ---------------------------------------------------------------- PFM

void put_f32_le(unsigned char* out, float value) {
    const auto bits = std::bit_cast<std::uint32_t>(value);
    for (int i = 0; i < 4; ++i) out[i] = static_cast<unsigned char>(bits >> (8 * i));
}

float get_f32(const unsigned char* in, bool little_endian) {
    std::uint32_t bits = 0;
    for (int i = 0; i < 4; ++i) {
        const int shift = little_endian ? 8 * i : 8 * (3 - i);
        bits |= static_cast<std::uint32_t>(in[i]) << shift;
    }
    return std::bit_cast<float>(bits);
}

// SPEC §6: "PF\nW H\n-1.0\n", little-endian float32 RGB, rows bottom to top.
void write_pfm(const fs::path& path, const Image& image) {
    io::AtomicFile file(path);
    const std::string header =
        "PF\n" + std::to_string(image.width) + " " + std::to_string(image.height) + "\n-1.0\n";
    file.write(header.data(), header.size());
    std::vector<unsigned char> row(static_cast<std::size_t>(image.width) * 12);
    for (int y = image.height - 1; y >= 0; --y) {
        unsigned char* out = row.data();
        for (int x = 0; x < image.width; ++x)
            for (int c = 0; c < 3; ++c, out += 4) put_f32_le(out, image.pixel(x, y)[c]);
        file.write(row.data(), row.size());
    }
    file.commit();
}

struct PfmHeader {
    int channels = 3;
    std::int64_t width = 0;
    std::int64_t height = 0;
    bool little_endian = true;
    std::size_t data_offset = 0;
};

/// The next whitespace-terminated token at or after pos; empty when the text
/// ends before the token does.
std::string_view next_token(std::string_view text, std::size_t& pos) {
    const auto is_space = [](char ch) { return std::isspace(static_cast<unsigned char>(ch)) != 0; };
    while (pos < text.size() && is_space(text[pos])) ++pos;
    const std::size_t begin = pos;
    while (pos < text.size() && !is_space(text[pos])) ++pos;
    if (pos >= text.size()) return {};
    return text.substr(begin, pos - begin);
}

template <typename T>
bool parse_number(std::string_view token, T& value) {
    const auto [end, ec] = std::from_chars(token.data(), token.data() + token.size(), value);
    return ec == std::errc() && end == token.data() + token.size() && !token.empty();
}

PfmHeader parse_pfm_header(const fs::path& path, std::string_view text) {
    PfmHeader h;
    if (text.size() < 3 || text[0] != 'P' || (text[1] != 'F' && text[1] != 'f') ||
        !std::isspace(static_cast<unsigned char>(text[2])))
        fail(path, "not a PFM file (expected \"PF\" or \"Pf\")");
    h.channels = text[1] == 'F' ? 3 : 1;
    std::size_t pos = 2;
    double scale = 0;
    if (!parse_number(next_token(text, pos), h.width) || !parse_number(next_token(text, pos), h.height))
        fail(path, "bad PFM header: expected the width and height");
    if (!parse_number(next_token(text, pos), scale) || !std::isfinite(scale) || scale == 0)
        fail(path, "bad PFM header: expected a nonzero scale (negative: little-endian)");
    check_size(path, h.width, h.height);
    h.little_endian = scale < 0;
    h.data_offset = pos + 1;  // exactly one whitespace character ends the header
    return h;
}

std::ifstream open_input(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    if (!in) fail(path, std::string("cannot open: ") + std::strerror(errno));
    return in;
}

std::vector<unsigned char> read_pfm_data(const fs::path& path, std::ifstream& in, const PfmHeader& h) {
    const auto expected = static_cast<std::uintmax_t>(h.width * h.height * h.channels * 4);
    std::error_code ec;
    const std::uintmax_t size = fs::file_size(path, ec);
    const std::uintmax_t available = !ec && size > h.data_offset ? size - h.data_offset : 0;
    if (ec || available < expected)
        fail(path, "truncated PFM: " + std::to_string(expected) + " bytes of pixel data expected, " +
                       std::to_string(available) + " found");
    std::vector<unsigned char> data(static_cast<std::size_t>(expected));
    in.clear();
    in.seekg(static_cast<std::streamoff>(h.data_offset));
    in.read(reinterpret_cast<char*>(data.data()), static_cast<std::streamsize>(data.size()));
    if (static_cast<std::uintmax_t>(in.gcount()) != expected) fail(path, "truncated PFM: read failed");
    return data;
}

Image pfm_to_image(const PfmHeader& h, const std::vector<unsigned char>& data) {
    Image image(static_cast<int>(h.width), static_cast<int>(h.height));
    const auto row_bytes = static_cast<std::size_t>(h.width * h.channels * 4);
    for (int y = 0; y < image.height; ++y) {
        const unsigned char* row = data.data() + static_cast<std::size_t>(image.height - 1 - y) * row_bytes;
        for (int x = 0; x < image.width; ++x) {
            float* p = image.pixel(x, y);
            const unsigned char* in =
                row + static_cast<std::size_t>(x) * static_cast<std::size_t>(h.channels) * 4;
            for (int c = 0; c < 3; ++c) p[c] = get_f32(in + (h.channels == 3 ? 4 * c : 0), h.little_endian);
            p[3] = 1.0f;
        }
    }
    return image;
}

// ---------------------------------------------------------------- PNG

using io::clamp01;
using io::srgb_encode;
using io::to_u8;

/// IEC 61966-2-1 transfer function, encoded → linear, v in [0, 1].
float srgb_decode(double v) {
    return static_cast<float>(v <= 0.04045 ? v / 12.92 : std::pow((v + 0.055) / 1.055, 2.4));
}

std::vector<std::uint8_t> png_pixels(const Image& image, int channels) {
    std::vector<std::uint8_t> out(pixel_count(image) * static_cast<std::size_t>(channels));
    for (std::size_t i = 0; i < pixel_count(image); ++i) {
        const float* p = &image.rgba[i * 4];
        std::uint8_t* q = &out[i * static_cast<std::size_t>(channels)];
        // RGBA PNG holds straight (not premultiplied) color, as viewers and
        // NeRF loaders expect: the film's premultiplied radiance is divided by α.
        const float a = p[3];
        const double scale = channels == 4 && a > 0.0f ? 1.0 / a : 1.0;
        for (int c = 0; c < 3; ++c) q[c] = to_u8(srgb_encode(clamp01(p[c] * scale)));
        if (channels == 4) q[3] = to_u8(clamp01(a));
    }
    return out;
}

std::vector<unsigned char> encode_png(const fs::path& path, const Image& image, bool alpha) {
    png_image png{};
    png.version = PNG_IMAGE_VERSION;
    png.width = static_cast<png_uint_32>(image.width);
    png.height = static_cast<png_uint_32>(image.height);
    png.format = alpha ? PNG_FORMAT_RGBA : PNG_FORMAT_RGB;
    const std::vector<std::uint8_t> pixels = png_pixels(image, alpha ? 4 : 3);
    png_alloc_size_t size = PNG_IMAGE_PNG_SIZE_MAX(png);
    std::vector<unsigned char> out(size);
    if (png_image_write_to_memory(&png, out.data(), &size, 0, pixels.data(), 0, nullptr) == 0) {
        const std::string message = png.message;
        png_image_free(&png);
        fail(path, "PNG encoding failed: " + message);
    }
    out.resize(size);
    return out;
}

void write_png(const fs::path& path, const Image& image, bool alpha) {
    const std::vector<unsigned char> bytes = encode_png(path, image, alpha);
    io::AtomicFile file(path);
    file.write(bytes.data(), bytes.size());
    file.commit();
}

// libpng reports errors by longjmp to the setjmp in read_png_header and
// read_png_pixels; those keep only trivially destructible state, and every
// C++ object lives in read_png, above them.
struct PngReader {
    png_structp png = nullptr;
    png_infop info = nullptr;
    std::array<char, 256> message{};
    PngReader() = default;
    PngReader(const PngReader&) = delete;
    PngReader& operator=(const PngReader&) = delete;
    ~PngReader() { png_destroy_read_struct(&png, &info, nullptr); }
};

struct PngLayout {
    png_uint_32 width = 0;
    png_uint_32 height = 0;
    int channels = 0;   // 3 or 4 after the transforms
    int bit_depth = 0;  // 8 or 16 after the transforms
    int passes = 1;
    std::size_t row_bytes = 0;
};

[[noreturn]] void on_png_error(png_structp png, png_const_charp message) {
    auto* reader = static_cast<PngReader*>(png_get_error_ptr(png));
    std::snprintf(reader->message.data(), reader->message.size(), "%s", message);
    png_longjmp(png, 1);
}

void on_png_warning(png_structp, png_const_charp) {}

/// Expands every PNG to 8- or 16-bit RGB or RGBA; returns the pass count.
int set_png_transforms(png_structp png, png_infop info) {
    const int color = png_get_color_type(png, info);
    if (color == PNG_COLOR_TYPE_PALETTE) png_set_palette_to_rgb(png);
    if (color == PNG_COLOR_TYPE_GRAY && png_get_bit_depth(png, info) < 8) png_set_expand_gray_1_2_4_to_8(png);
    if (png_get_valid(png, info, PNG_INFO_tRNS) != 0) png_set_tRNS_to_alpha(png);
    if (color == PNG_COLOR_TYPE_GRAY || color == PNG_COLOR_TYPE_GRAY_ALPHA) png_set_gray_to_rgb(png);
    return png_set_interlace_handling(png);
}

bool read_png_header(PngReader& r, std::FILE* file, PngLayout& layout) {
    if (setjmp(png_jmpbuf(r.png))) return false;
    png_init_io(r.png, file);
    png_read_info(r.png, r.info);
    layout.passes = set_png_transforms(r.png, r.info);
    png_read_update_info(r.png, r.info);
    layout.width = png_get_image_width(r.png, r.info);
    layout.height = png_get_image_height(r.png, r.info);
    layout.channels = png_get_channels(r.png, r.info);
    layout.bit_depth = png_get_bit_depth(r.png, r.info);
    layout.row_bytes = png_get_rowbytes(r.png, r.info);
    return true;
}

[[gnu::noinline]] void read_png_rows(png_structp png, unsigned char* data, const PngLayout& layout) {
    for (int pass = 0; pass < layout.passes; ++pass)
        for (png_uint_32 y = 0; y < layout.height; ++y)
            png_read_row(png, data + y * layout.row_bytes, nullptr);
}

bool read_png_pixels(PngReader& r, unsigned char* data, const PngLayout& layout) {
    if (setjmp(png_jmpbuf(r.png))) return false;
    read_png_rows(r.png, data, layout);
    return true;
}

const std::array<float, 256>& srgb8_table() {
    static const std::array<float, 256> table = [] {
        std::array<float, 256> t{};
        for (std::size_t i = 0; i < t.size(); ++i) t[i] = srgb_decode(static_cast<double>(i) / 255.0);
        return t;
    }();
    return table;
}

Image png_to_image(const std::vector<unsigned char>& data, const PngLayout& layout) {
    Image image(static_cast<int>(layout.width), static_cast<int>(layout.height));
    const bool wide = layout.bit_depth == 16;
    const auto& table = srgb8_table();
    const std::size_t samples = pixel_count(image) * static_cast<std::size_t>(layout.channels);
    for (std::size_t s = 0; s < samples; ++s) {
        const std::size_t pixel = s / static_cast<std::size_t>(layout.channels);
        const auto c = static_cast<int>(s % static_cast<std::size_t>(layout.channels));
        const unsigned code = wide ? (static_cast<unsigned>(data[2 * s]) << 8) | data[2 * s + 1] : data[s];
        const double v = wide ? code / 65535.0 : code / 255.0;
        float& out = image.rgba[pixel * 4 + static_cast<std::size_t>(c)];
        if (c == 3)
            out = static_cast<float>(v);
        else
            out = wide ? srgb_decode(v) : table[code];
    }
    if (layout.channels == 3)
        for (std::size_t i = 0; i < pixel_count(image); ++i) image.rgba[i * 4 + 3] = 1.0f;
    return image;
}

std::string png_error_reason(const PngReader& r) {
    const std::string message = r.message.data();
    return message == "Read Error" ? "truncated PNG (read error)" : "bad PNG: " + message;
}

struct FileCloser {
    void operator()(std::FILE* f) const { std::fclose(f); }
};

// ---------------------------------------------------------------- EXR

constexpr std::array<const char*, 4> kExrChannels = {"R", "G", "B", "A"};
constexpr std::size_t kExrXStride = 4 * sizeof(float);
constexpr const char* kExrDepth = "Z";
constexpr const char* kExrFirstHit = "FirstHit.Z";

void write_exr_file(const char* name, const Image& image) {
    Imf::Header header(image.width, image.height);
    header.compression() = Imf::ZIP_COMPRESSION;
    Imf::FrameBuffer frame;
    const std::size_t y_stride = kExrXStride * static_cast<std::size_t>(image.width);
    for (std::size_t c = 0; c < kExrChannels.size(); ++c) {
        header.channels().insert(kExrChannels[c], Imf::Channel(Imf::FLOAT));
        frame.insert(kExrChannels[c], Imf::Slice::Make(Imf::FLOAT, image.rgba.data() + c, Imath::V2i(0, 0),
                                                       image.width, image.height, kExrXStride, y_stride));
    }
    // Depth outputs as extra channels: "Z" (OpenEXR's name for depth) the
    // expected termination depth, "FirstHit.Z" the first-hit depth.
    const auto pixels = static_cast<std::size_t>(image.width) * static_cast<std::size_t>(image.height);
    auto extra = [&](const char* channel, const std::vector<float>& plane) {
        if (plane.size() != pixels) return;
        header.channels().insert(channel, Imf::Channel(Imf::FLOAT));
        frame.insert(channel,
                     Imf::Slice::Make(Imf::FLOAT, plane.data(), Imath::V2i(0, 0), image.width, image.height,
                                      sizeof(float), sizeof(float) * static_cast<std::size_t>(image.width)));
    };
    extra(kExrDepth, image.depth);
    extra(kExrFirstHit, image.first_hit);
    Imf::OutputFile out(name, header);
    out.setFrameBuffer(frame);
    out.writePixels(image.height);
}

void write_exr(const fs::path& path, const Image& image) {
    io::AtomicFile file(path);
    file.close();  // OpenEXR opens the temporary file by name
    try {
        write_exr_file(file.temp_path().c_str(), image);
    } catch (const std::exception& e) {
        fail(path, std::string("OpenEXR: ") + e.what());
    }
    file.commit();
}

Image read_exr_file(const fs::path& path) {
    Imf::InputFile file(path.c_str());
    const Imath::Box2i window = file.header().dataWindow();
    const std::int64_t width = std::int64_t{window.max.x} - window.min.x + 1;
    const std::int64_t height = std::int64_t{window.max.y} - window.min.y + 1;
    check_size(path, width, height);
    const Imf::ChannelList& channels = file.header().channels();
    if (!channels.findChannel("R") && !channels.findChannel("G") && !channels.findChannel("B"))
        fail(path, "no R, G or B channel");
    Image image(static_cast<int>(width), static_cast<int>(height));
    Imf::FrameBuffer frame;
    const std::size_t y_stride = kExrXStride * static_cast<std::size_t>(width);
    for (std::size_t c = 0; c < kExrChannels.size(); ++c)
        frame.insert(kExrChannels[c], Imf::Slice::Make(Imf::FLOAT, image.rgba.data() + c, window, kExrXStride,
                                                       y_stride, 1, 1, c == 3 ? 1.0 : 0.0));
    const auto pixels = static_cast<std::size_t>(width) * static_cast<std::size_t>(height);
    for (auto [channel, plane] :
         {std::pair{kExrDepth, &image.depth}, std::pair{kExrFirstHit, &image.first_hit}}) {
        if (!channels.findChannel(channel)) continue;
        plane->assign(pixels, 0.0f);
        frame.insert(channel, Imf::Slice::Make(Imf::FLOAT, plane->data(), window, sizeof(float),
                                               sizeof(float) * static_cast<std::size_t>(width)));
    }
    file.setFrameBuffer(frame);
    file.readPixels(window.min.y, window.max.y);
    return image;
}

}  // namespace

void write_image(const fs::path& path, const Image& image, bool png_alpha) {
    const std::string ext = lower_extension(path);
    if (ext.empty()) fail(path, "no file extension to choose the image format (expected .pfm, .png or .exr)");
    if (ext != ".pfm" && ext != ".png" && ext != ".exr")
        fail(path, "unknown image format '" + ext + "' (expected .pfm, .png or .exr)");
    check_writable(path, image);
    if (ext == ".pfm")
        write_pfm(path, image);
    else if (ext == ".png")
        write_png(path, image, png_alpha);
    else
        write_exr(path, image);
}

Image read_pfm(const fs::path& path) {
    std::ifstream in = open_input(path);
    std::string head(256, '\0');
    in.read(head.data(), static_cast<std::streamsize>(head.size()));
    head.resize(static_cast<std::size_t>(in.gcount()));
    const PfmHeader header = parse_pfm_header(path, head);
    return pfm_to_image(header, read_pfm_data(path, in, header));
}

Image read_png(const fs::path& path) {
    const std::unique_ptr<std::FILE, FileCloser> file(std::fopen(path.c_str(), "rb"));
    if (!file) fail(path, std::string("cannot open: ") + std::strerror(errno));
    PngReader r;
    r.png = png_create_read_struct(PNG_LIBPNG_VER_STRING, &r, on_png_error, on_png_warning);
    if (r.png) r.info = png_create_info_struct(r.png);
    if (!r.png || !r.info) fail(path, "out of memory");
    std::array<png_byte, 8> signature{};
    if (std::fread(signature.data(), 1, signature.size(), file.get()) != signature.size() ||
        png_sig_cmp(signature.data(), 0, signature.size()) != 0)
        fail(path, "not a PNG file");
    png_set_sig_bytes(r.png, static_cast<int>(signature.size()));
    PngLayout layout;
    if (!read_png_header(r, file.get(), layout)) fail(path, png_error_reason(r));
    check_size(path, layout.width, layout.height);
    std::vector<unsigned char> data(layout.row_bytes * layout.height);
    if (!read_png_pixels(r, data.data(), layout)) fail(path, png_error_reason(r));
    return png_to_image(data, layout);
}

Image read_exr(const fs::path& path) {
    try {
        return read_exr_file(path);
    } catch (const Error&) {
        throw;
    } catch (const std::exception& e) {
        fail(path, std::string("OpenEXR: ") + e.what());
    }
}

}  // namespace fathom
