// Image writers and readers (SPEC §6): PFM bytes and row order, PNG sRGB
// codes and colour types, EXR float round trips, atomic replacement.
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <functional>
#include <initializer_list>
#include <iterator>
#include <limits>
#include <stdexcept>
#include <string>
#include <vector>

#include <zlib.h>

#include "fathom/error.h"
#include "fathom/image.h"
#include "fathom/io.h"

#include "io/atomic_file.h"
#include "test_util.h"

namespace fathom {
namespace {

namespace fs = std::filesystem;
using test::TempDir;

std::string read_bytes(const fs::path& path) {
    std::ifstream in(path, std::ios::binary);
    return {std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
}

void write_bytes(const fs::path& path, const std::string& bytes) {
    std::ofstream out(path, std::ios::binary);
    out.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
}

float le_float(const std::string& bytes, std::size_t offset) {
    std::uint32_t bits = 0;
    for (int i = 0; i < 4; ++i)
        bits |= static_cast<std::uint32_t>(
                    static_cast<unsigned char>(bytes[offset + static_cast<std::size_t>(i)]))
                << (8 * i);
    return std::bit_cast<float>(bits);
}

std::string be_bytes(float v) {
    const auto bits = std::bit_cast<std::uint32_t>(v);
    std::string s(4, '\0');
    for (int i = 0; i < 4; ++i) s[static_cast<std::size_t>(i)] = static_cast<char>(bits >> (8 * (3 - i)));
    return s;
}

std::vector<std::string> dir_entries(const fs::path& dir) {
    std::vector<std::string> names;
    for (const auto& e : fs::directory_iterator(dir)) names.push_back(e.path().filename().string());
    return names;
}

bool has_temp_file(const fs::path& dir) {
    for (const auto& name : dir_entries(dir))
        if (name.find(".tmp") != std::string::npos) return true;
    return false;
}

/// Pixel (x, y) channel c = 100·y + 10·x + c (+ 0.5), all distinct.
Image numbered_image(int w, int h) {
    Image img(w, h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x)
            for (int c = 0; c < 4; ++c) img.pixel(x, y)[c] = static_cast<float>(100 * y + 10 * x + c) + 0.5f;
    return img;
}

/// The sRGB 8-bit code of a linear value, per SPEC §6 (clamp, encode, round).
double srgb_encode(double v) {
    v = std::isnan(v) ? 0.0 : std::clamp(v, 0.0, 1.0);
    return v <= 0.0031308 ? 12.92 * v : 1.055 * std::pow(v, 1.0 / 2.4) - 0.055;
}

int srgb_code(double v) {
    return static_cast<int>(std::lround(srgb_encode(v) * 255.0));
}

double srgb_decode(double e) {
    return e <= 0.04045 ? e / 12.92 : std::pow((e + 0.055) / 1.055, 2.4);
}

// ---- a minimal PNG encoder (filter 0, one IDAT) to test read_png independently of libpng's writer

void put_be32(std::string& s, std::uint32_t v) {
    for (int i = 3; i >= 0; --i) s.push_back(static_cast<char>(v >> (8 * i)));
}

void put_chunk(std::string& png, const char* type, const std::string& data) {
    put_be32(png, static_cast<std::uint32_t>(data.size()));
    const std::string body = std::string(type, 4) + data;
    png += body;
    put_be32(png, static_cast<std::uint32_t>(
                      crc32(0, reinterpret_cast<const Bytef*>(body.data()), static_cast<uInt>(body.size()))));
}

/// rows: the raw scanlines without filter bytes.
std::string make_png(std::uint32_t w, const std::vector<std::string>& rows, int depth, int color_type) {
    std::string ihdr;
    put_be32(ihdr, w);
    put_be32(ihdr, static_cast<std::uint32_t>(rows.size()));
    ihdr += {static_cast<char>(depth), static_cast<char>(color_type), 0, 0, 0};
    std::string raw;
    for (const auto& row : rows) raw += '\0' + row;
    uLongf size = compressBound(static_cast<uLong>(raw.size()));
    std::string z(size, '\0');
    compress(reinterpret_cast<Bytef*>(z.data()), &size, reinterpret_cast<const Bytef*>(raw.data()),
             static_cast<uLong>(raw.size()));
    z.resize(size);
    std::string png = "\x89PNG\r\n\x1a\n";
    put_chunk(png, "IHDR", ihdr);
    put_chunk(png, "IDAT", z);
    put_chunk(png, "IEND", "");
    return png;
}

std::string bytes_of(std::initializer_list<int> values) {
    std::string s;
    for (int v : values) s.push_back(static_cast<char>(v));
    return s;
}

// ================================================================ PFM

TEST(ImagePfm, HeaderBytesAndBottomToTopRows) {
    TempDir dir;
    const Image img = numbered_image(2, 3);
    write_image(dir / "a.pfm", img);
    const std::string bytes = read_bytes(dir / "a.pfm");
    const std::string header = "PF\n2 3\n-1.0\n";
    ASSERT_EQ(bytes.size(), header.size() + std::size_t{72});  // 2 × 3 pixels × 3 floats × 4 bytes
    EXPECT_EQ(bytes.substr(0, header.size()), header);
    for (int file_row = 0; file_row < 3; ++file_row)
        for (int x = 0; x < 2; ++x)
            for (int c = 0; c < 3; ++c) {
                const std::size_t offset =
                    header.size() + static_cast<std::size_t>((file_row * 2 + x) * 3 + c) * 4;
                EXPECT_EQ(le_float(bytes, offset), img.pixel(x, 2 - file_row)[c])
                    << file_row << " " << x << " " << c;
            }
    EXPECT_FALSE(has_temp_file(dir.path()));
}

TEST(ImagePfm, RoundTripIsBitExactWithoutClamping) {
    TempDir dir;
    Image img(3, 2);
    const std::array<float, 18> values = {0.0f,
                                          -0.0f,
                                          1.0f,
                                          -5.25f,
                                          1e30f,
                                          1e-40f /* subnormal */,
                                          std::numeric_limits<float>::infinity(),
                                          0.1f,
                                          3.0f,
                                          65504.5f,
                                          -1e-3f,
                                          7.0f,
                                          2.0f,
                                          0.5f,
                                          123456.789f,
                                          1e-7f,
                                          42.0f,
                                          std::numeric_limits<float>::quiet_NaN()};
    for (std::size_t i = 0; i < 6; ++i)
        for (std::size_t c = 0; c < 3; ++c) img.rgba[i * 4 + c] = values[i * 3 + c];
    write_image(dir / "r.PFM", img);
    const Image back = read_pfm(dir / "r.PFM");
    ASSERT_EQ(back.width, 3);
    ASSERT_EQ(back.height, 2);
    for (std::size_t i = 0; i < 6; ++i) {
        for (std::size_t c = 0; c < 3; ++c)
            EXPECT_EQ(std::bit_cast<std::uint32_t>(back.rgba[i * 4 + c]),
                      std::bit_cast<std::uint32_t>(img.rgba[i * 4 + c]));
        EXPECT_EQ(back.rgba[i * 4 + 3], 1.0f);
    }
}

TEST(ImagePfm, ReadsGreyBigEndian) {
    TempDir dir;
    // 2×2 grey, big-endian (positive scale); file rows bottom to top.
    write_bytes(dir / "g.pfm",
                "Pf\n2 2\n1.0\n" + be_bytes(1.0f) + be_bytes(2.0f) + be_bytes(3.0f) + be_bytes(4.0f));
    const Image img = read_pfm(dir / "g.pfm");
    ASSERT_EQ(img.width, 2);
    ASSERT_EQ(img.height, 2);
    const std::array<float, 4> expected = {3.0f, 4.0f, 1.0f, 2.0f};  // top row first
    for (int i = 0; i < 4; ++i) {
        const float* p = img.pixel(i % 2, i / 2);
        EXPECT_EQ(p[0], expected[static_cast<std::size_t>(i)]);
        EXPECT_EQ(p[1], p[0]);
        EXPECT_EQ(p[2], p[0]);
        EXPECT_EQ(p[3], 1.0f);
    }
}

void expect_error_naming(const fs::path& path, const std::function<void()>& f) {
    try {
        f();
        ADD_FAILURE() << "no exception for " << path;
    } catch (const Error& e) {
        EXPECT_EQ(e.subject(), path.string());
        EXPECT_NE(std::string(e.what()).find(path.filename().string()), std::string::npos) << e.what();
    }
}

TEST(ImagePfm, BadFilesThrowNamingTheFile) {
    TempDir dir;
    write_image(dir / "ok.pfm", numbered_image(4, 4));
    const std::string good = read_bytes(dir / "ok.pfm");
    write_bytes(dir / "trunc.pfm", good.substr(0, good.size() - 1));
    write_bytes(dir / "garbage.pfm", "hello, this is not a PFM file at all\n");
    write_bytes(dir / "huge.pfm", "PF\n100000 100000\n-1.0\n" + std::string(64, '\0'));
    write_bytes(dir / "zero.pfm", "PF\n0 5\n-1.0\n");
    write_bytes(dir / "noscale.pfm", "PF\n1 1\nabc\n" + std::string(12, '\0'));
    write_bytes(dir / "headeronly.pfm", "PF\n1 1\n-1.0");
    for (const char* name :
         {"trunc.pfm", "garbage.pfm", "huge.pfm", "zero.pfm", "noscale.pfm", "headeronly.pfm", "missing.pfm"})
        expect_error_naming(dir / name, [&] { (void)read_pfm(dir / name); });
}

// ================================================================ PNG

TEST(ImagePng, EncodesSrgbCodes) {
    TempDir dir;
    const std::array<float, 7> linear = {
        0.0f, 0.0031308f, 0.5f, 1.0f, 2.0f, -1.0f, std::numeric_limits<float>::quiet_NaN()};
    const std::array<int, 7> codes = {0, 10, 188, 255, 255, 0, 0};
    Image img(static_cast<int>(linear.size()), 1);
    for (int x = 0; x < img.width; ++x)
        for (int c = 0; c < 4; ++c) img.pixel(x, 0)[c] = linear[static_cast<std::size_t>(x)];
    write_image(dir / "s.png", img);
    const Image back = read_png(dir / "s.png");
    ASSERT_EQ(back.width, img.width);
    ASSERT_EQ(back.height, 1);
    for (int x = 0; x < img.width; ++x) {
        const auto i = static_cast<std::size_t>(x);
        EXPECT_EQ(srgb_code(linear[i]), codes[i]) << "the test's own formula, x = " << x;
        for (int c = 0; c < 3; ++c)
            EXPECT_EQ(srgb_code(back.pixel(x, 0)[c]), codes[i]) << "x = " << x << " c = " << c;
        EXPECT_FLOAT_EQ(back.pixel(x, 0)[0], static_cast<float>(srgb_decode(codes[i] / 255.0)));
        EXPECT_EQ(back.pixel(x, 0)[3], 1.0f);
    }
}

TEST(ImagePng, ColorTypeRgbOrRgbaAndLinearAlpha) {
    TempDir dir;
    Image img(2, 2);
    for (int i = 0; i < 4; ++i) {
        float* p = img.pixel(i % 2, i / 2);
        p[0] = p[1] = p[2] = 0.5f;
        p[3] = std::array<float, 4>{0.5f, 0.0f, 1.0f, 2.0f}[static_cast<std::size_t>(i)];
    }
    write_image(dir / "rgb.png", img, false);
    write_image(dir / "rgba.PNG", img, true);
    const std::string rgb = read_bytes(dir / "rgb.png");
    const std::string rgba = read_bytes(dir / "rgba.PNG");
    ASSERT_GT(rgb.size(), 26u);
    ASSERT_GT(rgba.size(), 26u);
    EXPECT_EQ(rgb.substr(12, 4), "IHDR");
    EXPECT_EQ(rgb[24], 8);  // bit depth
    EXPECT_EQ(rgb[25], 2);  // color type: RGB
    EXPECT_EQ(rgba[24], 8);
    EXPECT_EQ(rgba[25], 6);  // color type: RGBA
    const Image a = read_png(dir / "rgba.PNG");
    EXPECT_FLOAT_EQ(a.pixel(0, 0)[3], 128.0f / 255.0f);  // 0.5 · 255 + 0.5 → 128, not sRGB-encoded
    EXPECT_EQ(a.pixel(1, 0)[3], 0.0f);
    EXPECT_EQ(a.pixel(0, 1)[3], 1.0f);
    EXPECT_EQ(a.pixel(1, 1)[3], 1.0f);
    EXPECT_EQ(srgb_code(a.pixel(1, 0)[0]), 188);  // colour is kept where α = 0
    EXPECT_EQ(read_png(dir / "rgb.png").pixel(0, 0)[3], 1.0f);
}

TEST(ImagePng, DecodeRoundTripWithinOneCode) {
    TempDir dir;
    Image img(64, 5);
    for (std::size_t i = 0; i < img.rgba.size(); ++i)
        img.rgba[i] = static_cast<float>((i * 37) % 1000) / 997.0f;  // [0, 1.002]
    write_image(dir / "rt.png", img, true);
    const Image back = read_png(dir / "rt.png");
    ASSERT_EQ(back.width, 64);
    ASSERT_EQ(back.height, 5);
    for (std::size_t i = 0; i < img.rgba.size(); ++i) {
        if (i % 4 == 3) {
            EXPECT_NEAR(back.rgba[i], std::min(img.rgba[i], 1.0f), 0.5 / 255.0 + 1e-6) << i;
        } else {
            // RGBA PNG stores straight color: the film's (premultiplied) value over α.
            const float a = img.rgba[i - i % 4 + 3];
            const float want = a > 0.0f ? std::min(img.rgba[i] / a, 1.0f) : img.rgba[i];
            EXPECT_EQ(srgb_code(back.rgba[i]), srgb_code(want)) << i;
            EXPECT_NEAR(srgb_encode(back.rgba[i]), srgb_encode(want), 0.5 / 255.0 + 1e-6) << i;
        }
    }
}

TEST(ImagePng, ReadsGreyPaletteAnd16BitFiles) {
    TempDir dir;
    // 8-bit grey, 2×1: codes 0 and 188.
    write_bytes(dir / "g8.png", make_png(2, {bytes_of({0, 188})}, 8, 0));
    const Image g8 = read_png(dir / "g8.png");
    ASSERT_EQ(g8.width, 2);
    EXPECT_EQ(g8.pixel(0, 0)[0], 0.0f);
    EXPECT_FLOAT_EQ(g8.pixel(1, 0)[1], static_cast<float>(srgb_decode(188 / 255.0)));
    EXPECT_EQ(g8.pixel(1, 0)[3], 1.0f);
    // 16-bit grey + alpha, 1×2: (0x8000, 0xFFFF) then (0xFFFF, 0x0000).
    write_bytes(dir / "ga16.png",
                make_png(1, {bytes_of({0x80, 0, 0xFF, 0xFF}), bytes_of({0xFF, 0xFF, 0, 0})}, 16, 4));
    const Image ga = read_png(dir / "ga16.png");
    ASSERT_EQ(ga.height, 2);
    EXPECT_FLOAT_EQ(ga.pixel(0, 0)[2], static_cast<float>(srgb_decode(32768 / 65535.0)));
    EXPECT_EQ(ga.pixel(0, 0)[3], 1.0f);
    EXPECT_EQ(ga.pixel(0, 1)[0], 1.0f);
    EXPECT_EQ(ga.pixel(0, 1)[3], 0.0f);
    // 16-bit RGB, 1×1.
    write_bytes(dir / "rgb16.png", make_png(1, {bytes_of({0, 0, 0xFF, 0xFF, 0x40, 0x00})}, 16, 2));
    const Image c = read_png(dir / "rgb16.png");
    EXPECT_EQ(c.pixel(0, 0)[0], 0.0f);
    EXPECT_EQ(c.pixel(0, 0)[1], 1.0f);
    EXPECT_FLOAT_EQ(c.pixel(0, 0)[2], static_cast<float>(srgb_decode(0x4000 / 65535.0)));
    EXPECT_EQ(c.pixel(0, 0)[3], 1.0f);
}

TEST(ImagePng, BadFilesThrowNamingTheFile) {
    TempDir dir;
    write_image(dir / "ok.png", numbered_image(16, 16));
    const std::string good = read_bytes(dir / "ok.png");
    write_bytes(dir / "trunc.png", good.substr(0, good.size() / 2));
    write_bytes(dir / "garbage.png", "definitely not a PNG file, just text\n");
    write_bytes(dir / "empty.png", "");
    for (const char* name : {"trunc.png", "garbage.png", "empty.png", "missing.png"})
        expect_error_naming(dir / name, [&] { (void)read_png(dir / name); });
}

// ================================================================ EXR

TEST(ImageExr, RoundTripIsBitExactIncludingAlpha) {
    TempDir dir;
    Image img(5, 3);
    for (std::size_t i = 0; i < img.rgba.size(); ++i)
        img.rgba[i] =
            (i % 2 == 0 ? 1.0f : -1.0f) * static_cast<float>(i) * 0.1f + 1e-7f * static_cast<float>(i * i);
    img.rgba[3] = 0.123456789f;
    img.rgba[7] = 1e20f;
    write_image(dir / "e.exr", img);
    const Image back = read_exr(dir / "e.exr");
    ASSERT_EQ(back.width, 5);
    ASSERT_EQ(back.height, 3);
    ASSERT_EQ(back.rgba.size(), img.rgba.size());
    for (std::size_t i = 0; i < img.rgba.size(); ++i)
        EXPECT_EQ(std::bit_cast<std::uint32_t>(back.rgba[i]), std::bit_cast<std::uint32_t>(img.rgba[i])) << i;
    EXPECT_EQ(read_bytes(dir / "e.exr").substr(0, 4), std::string("\x76\x2f\x31\x01", 4));  // EXR magic
}

TEST(ImageExr, BadFilesThrowNamingTheFile) {
    TempDir dir;
    write_bytes(dir / "garbage.exr", "not an OpenEXR file");
    for (const char* name : {"garbage.exr", "missing.exr"})
        expect_error_naming(dir / name, [&] { (void)read_exr(dir / name); });
}

// ================================================================ atomic writes

TEST(ImageWrite, MissingDirectoryThrowsAndLeavesNoFile) {
    TempDir dir;
    const Image img = numbered_image(2, 2);
    for (const char* name : {"x.pfm", "x.png", "x.exr"}) {
        const fs::path target = dir / "no_such_dir" / name;
        expect_error_naming(target, [&] { write_image(target, img); });
        EXPECT_FALSE(fs::exists(target));
    }
    EXPECT_TRUE(dir_entries(dir.path()).empty());
}

TEST(ImageWrite, UnknownExtensionThrowsAndLeavesNoFile) {
    TempDir dir;
    const Image img = numbered_image(2, 2);
    try {
        write_image(dir / "x.TIFF", img);
        ADD_FAILURE() << "no exception";
    } catch (const Error& e) {
        EXPECT_EQ(e.reason(), "unknown image format '.tiff' (expected .pfm, .png or .exr)");
        EXPECT_EQ(e.subject(), (dir / "x.TIFF").string());
    }
    EXPECT_THROW(write_image(dir / "noext", img), Error);
    EXPECT_TRUE(dir_entries(dir.path()).empty());
}

TEST(ImageWrite, EmptyImageThrowsAndLeavesNoFile) {
    TempDir dir;
    for (const char* name : {"e.pfm", "e.png", "e.exr"})
        EXPECT_THROW(write_image(dir / name, Image()), Error);
    Image inconsistent(2, 2);
    inconsistent.rgba.resize(3);
    EXPECT_THROW(write_image(dir / "i.pfm", inconsistent), Error);
    EXPECT_TRUE(dir_entries(dir.path()).empty());
}

TEST(ImageWrite, ReplacesAnExistingTargetWhole) {
    TempDir dir;
    const Image img = numbered_image(3, 2);
    for (const char* name : {"t.pfm", "t.png", "t.exr"}) {
        const fs::path target = dir / name;
        write_bytes(target, std::string(1 << 20, 'x'));  // larger than any of the new files
        write_image(target, img, true);
        const std::string bytes = read_bytes(target);
        EXPECT_LT(bytes.size(), 1u << 16) << name;
        EXPECT_EQ(bytes.find("xxxx"), std::string::npos) << name;
    }
    EXPECT_EQ(read_pfm(dir / "t.pfm").pixel(2, 1)[2], img.pixel(2, 1)[2]);
    EXPECT_EQ(read_exr(dir / "t.exr").pixel(2, 1)[3], img.pixel(2, 1)[3]);
    EXPECT_EQ(read_bytes(dir / "t.pfm").size(), std::string("PF\n3 2\n-1.0\n").size() + std::size_t{72});
    EXPECT_EQ(dir_entries(dir.path()).size(), 3u);
    EXPECT_FALSE(has_temp_file(dir.path()));
}

TEST(ImageAtomicFile, UncommittedWriteLeavesTargetAndNoTempFile) {
    TempDir dir;
    const fs::path target = dir / "keep.bin";
    write_bytes(target, "old");
    try {
        io::AtomicFile file(target);
        EXPECT_EQ(file.temp_path().parent_path(), dir.path());
        EXPECT_EQ(file.temp_path().filename().string().rfind(".keep.bin.tmp-", 0), 0u) << file.temp_path();
        EXPECT_TRUE(fs::exists(file.temp_path()));
        file.write("new contents", 12);
        throw std::runtime_error("failure in the middle of a write");
    } catch (const std::runtime_error&) {
    }
    EXPECT_EQ(read_bytes(target), "old");
    EXPECT_FALSE(has_temp_file(dir.path()));
    EXPECT_EQ(dir_entries(dir.path()).size(), 1u);
}

TEST(ImageAtomicFile, CommitRenamesOverTheTarget) {
    TempDir dir;
    const fs::path target = dir / "t.bin";
    write_bytes(target, "a much longer old content");
    {
        io::AtomicFile a(target);
        io::AtomicFile b(target);
        EXPECT_NE(a.temp_path(), b.temp_path());
        a.write("new", 3);
        a.commit();
        EXPECT_EQ(read_bytes(target), "new");
    }
    EXPECT_EQ(read_bytes(target), "new");
    EXPECT_FALSE(has_temp_file(dir.path()));
}

}  // namespace
}  // namespace fathom
