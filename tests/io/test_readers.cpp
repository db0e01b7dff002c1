// Volume readers (raw, NRRD, MetaImage, read_volume) and describe_volume.
#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <zlib.h>

#include "fathom/error.h"
#include "fathom/info.h"
#include "fathom/io.h"
#include "fathom/log.h"

#include "test_util.h"

using namespace fathom;
using fathom::test::expect_error;
using fathom::test::TempDir;
namespace fs = std::filesystem;

namespace {

void write_file(const fs::path& p, const std::string& bytes) {
    std::ofstream f(p, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(f.good()) << p;
}

std::string read_whole(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

/// Samples as bytes in the requested byte order.
template <class T>
std::string bytes_of(const std::vector<T>& values, bool big_endian = false) {
    std::string out(values.size() * sizeof(T), '\0');
    std::memcpy(out.data(), values.data(), out.size());
    if (big_endian != (std::endian::native == std::endian::big))
        for (std::size_t i = 0; i < out.size(); i += sizeof(T))
            std::reverse(out.begin() + i, out.begin() + i + sizeof(T));
    return out;
}

/// A gzip member (deflate with a gzip wrapper), with `header`'s optional
/// fields when given.
std::string gzip(const std::string& data, gz_header* header = nullptr) {
    z_stream zs{};
    EXPECT_EQ(deflateInit2(&zs, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
    if (header != nullptr) {
        EXPECT_EQ(deflateSetHeader(&zs, header), Z_OK);
    }
    std::string out(deflateBound(&zs, data.size()) + 64, '\0');
    zs.next_in = reinterpret_cast<Bytef*>(const_cast<char*>(data.data()));
    zs.avail_in = static_cast<uInt>(data.size());
    zs.next_out = reinterpret_cast<Bytef*>(out.data());
    zs.avail_out = static_cast<uInt>(out.size());
    EXPECT_EQ(deflate(&zs, Z_FINISH), Z_STREAM_END);
    out.resize(zs.total_out);
    deflateEnd(&zs);
    return out;
}

/// A zlib stream, as MetaIO writes CompressedData.
std::string zlib_compress(const std::string& data) {
    uLongf n = compressBound(data.size());
    std::string out(n, '\0');
    EXPECT_EQ(compress(reinterpret_cast<Bytef*>(out.data()), &n, reinterpret_cast<const Bytef*>(data.data()),
                       data.size()),
              Z_OK);
    out.resize(n);
    return out;
}

/// 0, 1, 2, ... as T (the value at node n is n % modulo).
template <class T>
std::vector<T> ramp(std::size_t n, long modulo = 1000, long offset = 0) {
    std::vector<T> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<T>(static_cast<long>(i) % modulo + offset);
    return v;
}

/// Collects warnings for the scope's lifetime.
class WarningCatcher {
public:
    WarningCatcher() : previous_(set_warning_sink([this](const std::string& m) { messages.push_back(m); })) {}
    ~WarningCatcher() { set_warning_sink(previous_); }
    WarningCatcher(const WarningCatcher&) = delete;
    WarningCatcher& operator=(const WarningCatcher&) = delete;
    std::vector<std::string> messages;

private:
    WarningSink previous_;
};

const std::string kHeader443 = "NRRD0005\ntype: uint16\ndimension: 3\nsizes: 4 4 3\nendian: little\n";

std::vector<std::uint16_t> volume_u16(const Volume& v) {
    std::vector<std::uint16_t> out(v.size_bytes() / 2);
    std::memcpy(out.data(), v.bytes(), v.size_bytes());
    return out;
}

}  // namespace

// ================================================================ raw

TEST(RawReader, InfersLayoutFromName) {
    auto a = infer_raw_layout("lidc2_256x256x133_uint8.raw");
    ASSERT_TRUE(a);
    EXPECT_EQ(a->dims, (std::array<std::int64_t, 3>{256, 256, 133}));
    EXPECT_EQ(a->dtype, DType::u8);
    auto b = infer_raw_layout("/data/bunny_512x512x361_uint16be.raw");
    ASSERT_TRUE(b);
    EXPECT_EQ(b->dtype, DType::u16);
    EXPECT_TRUE(b->big_endian);
    auto dbl = infer_raw_layout("x_2x2x2_double.raw");  // "double" ends in "le" but is no byte-order suffix
    ASSERT_TRUE(dbl);
    EXPECT_EQ(dbl->dtype, DType::f64);
    EXPECT_FALSE(dbl->big_endian);
    auto dbe = infer_raw_layout("x_2x2x2_doublebe.raw");
    ASSERT_TRUE(dbe);
    EXPECT_TRUE(dbe->big_endian);
    auto c = infer_raw_layout("x_10x20x30_float32.raw");
    ASSERT_TRUE(c);
    EXPECT_EQ(c->dtype, DType::f32);
    EXPECT_EQ(c->dims[2], 30);
    auto d = infer_raw_layout("y_4x4x4_int16le.raw.gz");
    ASSERT_TRUE(d);
    EXPECT_EQ(d->dtype, DType::i16);
    EXPECT_FALSE(d->big_endian);
    EXPECT_FALSE(infer_raw_layout("head.raw"));
    EXPECT_FALSE(infer_raw_layout("head_256x256_uint8.raw"));
    EXPECT_FALSE(infer_raw_layout("head_256x256x10_complex64.raw"));
}

TEST(RawReader, ReadsBigEndianWithHeaderAndPlacement) {
    TempDir dir;
    const auto values = ramp<std::int16_t>(24, 1000, -5);
    write_file(dir / "v.raw", "HDR!" + bytes_of(values, true));
    RawLayout layout;
    layout.dims = {4, 3, 2};
    layout.dtype = DType::i16;
    layout.big_endian = true;
    layout.header_bytes = 4;
    layout.spacing = {0.5, 1, 2};
    layout.origin = {1, 2, 3};
    const Volume v = read_raw(dir / "v.raw", layout);
    EXPECT_EQ(v.value(0, 0, 0), -5);
    EXPECT_EQ(v.value(3, 2, 1), 18);
    EXPECT_DOUBLE_EQ(v.spacing().z, 2.0);
    EXPECT_DOUBLE_EQ(v.origin().y, 2.0);
}

TEST(RawReader, ShortFileIsAnErrorLongerFileAWarning) {
    TempDir dir;
    RawLayout layout;
    layout.dims = {4, 4, 4};
    write_file(dir / "short.raw", std::string(63, 'a'));
    expect_error([&] { read_raw(dir / "short.raw", layout); }, dir / "short.raw",
                 {"holds 63 bytes, expected 64"});
    layout.header_bytes = 10;
    expect_error([&] { read_raw(dir / "short.raw", layout); }, dir / "short.raw", {"expected 74"});
    layout.header_bytes = 0;
    write_file(dir / "long.raw", std::string(70, 'a'));
    WarningCatcher warnings;
    const Volume v = read_raw(dir / "long.raw", layout);
    EXPECT_EQ(v.value(3, 3, 3), 'a');
    ASSERT_EQ(warnings.messages.size(), 1u);
    EXPECT_NE(warnings.messages[0].find("long.raw"), std::string::npos);
    EXPECT_NE(warnings.messages[0].find("6 bytes"), std::string::npos);
}

TEST(RawReader, GzipRawByNameThroughReadVolume) {
    TempDir dir;
    const auto values = ramp<std::uint16_t>(64);
    write_file(dir / "y_4x4x4_uint16be.raw.gz", gzip(bytes_of(values, true)));
    const Volume v = read_volume(dir / "y_4x4x4_uint16be.raw.gz");
    EXPECT_EQ(volume_u16(v), values);
}

TEST(RawReader, RefusesBadLayouts) {
    TempDir dir;
    write_file(dir / "a.raw", std::string(64, 'a'));
    RawLayout layout;
    layout.dims = {4, 4, 0};
    expect_error([&] { read_raw(dir / "a.raw", layout); }, dir / "a.raw", {"dims"});
    layout.dims = {4, 4, 4};
    layout.spacing = {1, 0, 1};
    expect_error([&] { read_raw(dir / "a.raw", layout); }, dir / "a.raw", {"spacing"});
    layout.spacing = {1, 1, 1};
    layout.dims = {1 << 20, 1 << 20, 1 << 10};
    expect_error([&] { read_raw(dir / "a.raw", layout); }, dir / "a.raw", {"limit"});
}

// ================================================================ NRRD, synthetic

TEST(NrrdReader, AttachedRaw) {
    TempDir dir;
    const auto values = ramp<std::uint16_t>(48);
    write_file(dir / "a.nrrd",
               kHeader443 + "encoding: raw\nspacings: 0.5 1 2\nspace origin: (1,2,3)\n\n" + bytes_of(values));
    const Volume v = read_nrrd(dir / "a.nrrd");
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{4, 4, 3}));
    EXPECT_EQ(v.dtype(), DType::u16);
    EXPECT_EQ(volume_u16(v), values);
    EXPECT_DOUBLE_EQ(v.spacing().x, 0.5);
    EXPECT_DOUBLE_EQ(v.spacing().z, 2.0);
    EXPECT_DOUBLE_EQ(v.origin().z, 3.0);
}

TEST(NrrdReader, AttachedGzipWithCommentsKeyValuesAndCrlf) {
    TempDir dir;
    const auto values = ramp<std::uint16_t>(48, 7);
    write_file(dir / "g.nrrd",
               "NRRD0004\r\n# a comment\r\nmy key:=my value\r\ntype: unsigned short\r\n"
               "dimension: 3\r\nsizes: 4 4 3\r\nendian: little\r\nencoding: gzip\r\n"
               "centers: cell cell cell\r\nunits: \"mm\" \"mm\" \"mm\"\r\n\r\n" +
                   gzip(bytes_of(values)));
    EXPECT_EQ(volume_u16(read_nrrd(dir / "g.nrrd")), values);
}

TEST(NrrdReader, GzipByteSkipIsInTheStreamLineSkipInTheFile) {
    TempDir dir;
    const auto values = ramp<std::uint16_t>(48);
    write_file(dir / "d.raw.gz", "junk line\n" + gzip("0123456" + bytes_of(values)));
    write_file(dir / "d.nhdr",
               kHeader443 + "encoding: gz\nline skip: 1\nbyte skip: 7\ndata file: d.raw.gz\n");
    EXPECT_EQ(volume_u16(read_nrrd(dir / "d.nhdr")), values);
}

TEST(NrrdReader, ConcatenatedGzipMembers) {
    TempDir dir;
    const std::string bytes = bytes_of(ramp<std::uint16_t>(48));
    write_file(dir / "c.gz", gzip(bytes.substr(0, 30)) + gzip(bytes.substr(30)));
    write_file(dir / "c.nhdr", kHeader443 + "encoding: gzip\ndata file: c.gz\n");
    EXPECT_EQ(read_whole(dir / "c.gz").size() > 0, true);
    const Volume v = read_nrrd(dir / "c.nhdr");
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(v.bytes()), v.size_bytes()), bytes);
}

// A gzip header with every optional field (extra, name, comment, header
// CRC), followed by a plain member, and a zlib stream under "encoding: gzip".
TEST(NrrdReader, GzipOptionalHeaderFieldsAndZlibStreams) {
    TempDir dir;
    const std::string bytes = bytes_of(ramp<std::uint16_t>(48));
    std::string extra("AB\x04\x00wxyz", 8), name = "slice.raw", comment = "fathom test";
    gz_header h{};
    h.extra = reinterpret_cast<Bytef*>(extra.data());
    h.extra_len = static_cast<uInt>(extra.size());
    h.name = reinterpret_cast<Bytef*>(name.data());
    h.comment = reinterpret_cast<Bytef*>(comment.data());
    h.hcrc = 1;
    std::string member = gzip(bytes.substr(0, 40), &h);
    ASSERT_EQ(static_cast<unsigned char>(member[3]), 0x1Eu);  // FHCRC | FEXTRA | FNAME | FCOMMENT
    write_file(dir / "h.gz", member + gzip(bytes.substr(40)));
    write_file(dir / "h.nhdr", kHeader443 + "encoding: gzip\ndata file: h.gz\n");
    Volume v = read_nrrd(dir / "h.nhdr");
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(v.bytes()), v.size_bytes()), bytes);
    write_file(dir / "z.nrrd", kHeader443 + "encoding: gzip\n\n" + zlib_compress(bytes));
    v = read_nrrd(dir / "z.nrrd");
    EXPECT_EQ(std::string(reinterpret_cast<const char*>(v.bytes()), v.size_bytes()), bytes);
    member[10] = static_cast<char>(member[10] ^ 0x01);  // the extra field's length: the header CRC breaks
    write_file(dir / "b.nrrd", kHeader443 + "encoding: gzip\n\n" + member + gzip(bytes.substr(40)));
    expect_error([&] { read_nrrd(dir / "b.nrrd"); }, dir / "b.nrrd", {"corrupt"});
}

TEST(NrrdReader, AsciiEncoding) {
    TempDir dir;
    std::string text;
    for (int i = 0; i < 8; ++i) text += std::to_string(i * 10 - 30) + (i % 3 == 2 ? "\n" : " ");
    write_file(dir / "t.nrrd",
               "NRRD0001\ntype: short\ndimension: 3\nsizes: 2 2 2\nencoding: text\n\n" + text);
    const Volume v = read_nrrd(dir / "t.nrrd");
    EXPECT_EQ(v.dtype(), DType::i16);
    EXPECT_EQ(v.value(0, 0, 0), -30);
    EXPECT_EQ(v.value(1, 1, 1), 40);
    write_file(dir / "f.nrrd",
               "NRRD0004\ntype: double\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n"
               "0.5, 1e-3, -2.25 3\n4 5 6 7.125\n");
    EXPECT_DOUBLE_EQ(read_nrrd(dir / "f.nrrd").value(1, 1, 1), 7.125);
    write_file(dir / "o.nrrd",
               "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2 2\nencoding: ascii\n\n"
               "1 2 3 4 5 6 7 300\n");
    expect_error([&] { read_nrrd(dir / "o.nrrd"); }, dir / "o.nrrd", {"value 7", "300"});
}

TEST(NrrdReader, BigEndianFloatDetached) {
    TempDir dir;
    std::vector<float> values(27);
    for (std::size_t i = 0; i < values.size(); ++i) values[i] = 0.25f * static_cast<float>(i) - 1.0f;
    write_file(dir / "f.raw", bytes_of(values, true));
    write_file(dir / "f.nhdr",
               "NRRD0004\ntype: float\ndimension: 3\nsizes: 3 3 3\nendian: big\n"
               "encoding: raw\ndata file: ./f.raw\n");
    const Volume v = read_nrrd(dir / "f.nhdr");
    ASSERT_EQ(v.dtype(), DType::f32);
    for (std::size_t i = 0; i < values.size(); ++i) EXPECT_EQ(v.data<float>()[i], values[i]);
}

TEST(NrrdReader, ListDataFilesAndPattern) {
    TempDir dir;
    const auto values = ramp<std::uint16_t>(48);
    const std::string bytes = bytes_of(values);
    for (int k = 0; k < 3; ++k) {
        write_file(dir / ("s" + std::to_string(k) + ".raw"),
                   bytes.substr(static_cast<std::size_t>(k) * 32, 32));
        write_file(dir / ("p" + std::string(k + 1 < 10 ? "00" : "0") + std::to_string(k + 1) + ".raw"),
                   bytes.substr(static_cast<std::size_t>(k) * 32, 32));
    }
    write_file(dir / "l.nhdr", kHeader443 + "encoding: raw\ndata file: LIST\ns0.raw\ns1.raw\ns2.raw\n");
    EXPECT_EQ(volume_u16(read_nrrd(dir / "l.nhdr")), values);
    write_file(dir / "p.nhdr", kHeader443 + "encoding: raw\ndatafile: p%03d.raw 1 3 1 2\n");
    EXPECT_EQ(volume_u16(read_nrrd(dir / "p.nhdr")), values);
    write_file(dir / "q.nhdr", kHeader443 + "encoding: raw\ndata file: p%03d.raw 1 2 1\n");
    expect_error([&] { read_nrrd(dir / "q.nhdr"); }, dir / "q.nhdr", {"data file", "2 files, expected 3"});
    write_file(dir / "r.nhdr", kHeader443 + "encoding: raw\ndata file: LIST\ns0.raw\ns1.raw\n");
    expect_error([&] { read_nrrd(dir / "r.nhdr"); }, dir / "r.nhdr", {"LIST", "expected 3"});
}

TEST(NrrdReader, RasSpaceIsNegatedToLps) {
    TempDir dir;
    write_file(dir / "r.nrrd", kHeader443 +
                                   "encoding: raw\nspace: right-anterior-superior\n"
                                   "space directions: (1,0,0) (0,2,0) (0,0,3)\nspace origin: (10,20,30)\n\n" +
                                   bytes_of(ramp<std::uint16_t>(48)));
    const Volume v = read_nrrd(dir / "r.nrrd");
    EXPECT_DOUBLE_EQ(v.axes().m[0][0], -1.0);
    EXPECT_DOUBLE_EQ(v.axes().m[1][1], -2.0);
    EXPECT_DOUBLE_EQ(v.axes().m[2][2], 3.0);
    EXPECT_EQ(v.origin(), (Vec3{-10, -20, 30}));
    write_file(dir / "l.nrrd", kHeader443 +
                                   "encoding: raw\nspace: LAS\nspace directions: (1,0,0) (0,2,0) (0,0,3)\n"
                                   "space origin: (10,20,30)\n\n" +
                                   bytes_of(ramp<std::uint16_t>(48)));
    EXPECT_EQ(read_nrrd(dir / "l.nrrd").origin(), (Vec3{10, -20, 30}));
}

TEST(NrrdReader, NonDiagonalDirectionsAreKept) {
    TempDir dir;
    write_file(dir / "o.nrrd", kHeader443 +
                                   "encoding: raw\nspace: left-posterior-superior\n"
                                   "space directions: (0.6,0.8,0) (-0.8,0.6,0) (0,0,2.5)\n\n" +
                                   bytes_of(ramp<std::uint16_t>(48)));
    const Volume v = read_nrrd(dir / "o.nrrd");
    EXPECT_DOUBLE_EQ(v.axes().m[1][0], 0.8);
    EXPECT_DOUBLE_EQ(v.axes().m[0][1], -0.8);
    EXPECT_DOUBLE_EQ(v.spacing().z, 2.5);
    const Vec3 p = v.index_to_world({1, 1, 1});
    EXPECT_NEAR(p.x, -0.2, 1e-12);
    EXPECT_NEAR(p.y, 1.4, 1e-12);
}

TEST(NrrdReader, FourDimensionalRgb) {
    TempDir dir;
    const auto values = ramp<std::uint8_t>(72, 251);
    write_file(dir / "c.nrrd",
               "NRRD0005\ntype: uint8\ndimension: 4\nsizes: 3 2 3 4\nencoding: raw\n"
               "kinds: RGB-color domain domain domain\nspace: LPS\n"
               "space directions: none (2,0,0) (0,2,0) (0,0,2)\n\n" +
                   bytes_of(values));
    const Volume v = read_nrrd(dir / "c.nrrd");
    EXPECT_EQ(v.components(), 3);
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{2, 3, 4}));
    EXPECT_EQ(v.value(1, 0, 0, 2), 5);
    EXPECT_DOUBLE_EQ(v.spacing().y, 2.0);
    write_file(dir / "s.nrrd",
               "NRRD0005\ntype: float\ndimension: 4\nsizes: 3 2 2 2\nencoding: raw\nendian: little\n"
               "spacings: nan 1 1 1\n\n" +
                   bytes_of(std::vector<float>(24, 0.5f)));
    EXPECT_EQ(read_nrrd(dir / "s.nrrd").components(), 3);
    write_file(dir / "b.nrrd",
               "NRRD0005\ntype: uint8\ndimension: 4\nsizes: 3 2 3 4\nencoding: raw\n"
               "kinds: domain domain domain domain\n\n" +
                   bytes_of(values));
    expect_error([&] { read_nrrd(dir / "b.nrrd"); }, dir / "b.nrrd", {"kinds"});
    write_file(dir / "t.nrrd", "NRRD0005\ntype: uint8\ndimension: 4\nsizes: 4 2 3 4\nencoding: raw\n\n" +
                                   bytes_of(ramp<std::uint8_t>(96)));
    expect_error([&] { read_nrrd(dir / "t.nrrd"); }, dir / "t.nrrd", {"sizes", "size 1 or 3"});
}

// Big-endian samples come out whole and in order: from gzip members split
// inside a sample, and from raw data of several MB.
TEST(NrrdReader, BigEndianSwappedAcrossMembersAndChunks) {
    TempDir dir;
    const auto values = ramp<std::uint16_t>(48);
    const std::string be = bytes_of(values, true);
    write_file(dir / "m.gz", gzip(be.substr(0, 31)) + gzip(be.substr(31)));
    write_file(dir / "m.nhdr",
               "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 4 4 3\nendian: big\nencoding: gzip\n"
               "data file: m.gz\n");
    EXPECT_EQ(volume_u16(read_nrrd(dir / "m.nhdr")), values);

    const auto big = ramp<std::uint16_t>(1100 * 1000 * 2);  // 4.4 MB
    write_file(dir / "l.raw", bytes_of(big, true));
    write_file(dir / "l.nhdr",
               "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 1100 1000 2\nendian: big\nencoding: raw\n"
               "data file: l.raw\n");
    EXPECT_EQ(volume_u16(read_nrrd(dir / "l.nhdr")), big);
}

TEST(NrrdReader, ByteSkipMinusOneReadsTheEnd) {
    TempDir dir;
    const auto values = ramp<std::uint16_t>(48);
    write_file(dir / "e.raw", std::string(123, 'x') + bytes_of(values, true));
    write_file(dir / "e.nhdr",
               "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 4 4 3\nendian: big\nencoding: raw\n"
               "byte skip: -1\ndata file: e.raw\n");
    EXPECT_EQ(volume_u16(read_nrrd(dir / "e.nhdr")), values);
    write_file(dir / "g.nhdr",
               "NRRD0004\ntype: uint16\ndimension: 3\nsizes: 4 4 3\nendian: big\nencoding: gzip\n"
               "byte skip: -1\ndata file: e.raw\n");
    expect_error([&] { read_nrrd(dir / "g.nhdr"); }, dir / "g.nhdr", {"byte skip", "raw"});
}

TEST(NrrdReader, AcceptsTypeAliases) {
    TempDir dir;
    const std::vector<std::pair<std::string, DType>> aliases{{"uchar", DType::u8},
                                                             {"unsigned char", DType::u8},
                                                             {"uint8_t", DType::u8},
                                                             {"signed char", DType::i8},
                                                             {"int8", DType::i8},
                                                             {"short", DType::i16},
                                                             {"short int", DType::i16},
                                                             {"signed short", DType::i16},
                                                             {"int16", DType::i16},
                                                             {"ushort", DType::u16},
                                                             {"unsigned short", DType::u16},
                                                             {"uint16", DType::u16},
                                                             {"int", DType::i32},
                                                             {"int32", DType::i32},
                                                             {"uint", DType::u32},
                                                             {"unsigned int", DType::u32},
                                                             {"uint32", DType::u32},
                                                             {"float", DType::f32},
                                                             {"double", DType::f64}};
    for (const auto& [name, type] : aliases) {
        const std::string data(8 * dtype_size(type), '\0');
        write_file(dir / "t.nrrd", "NRRD0004\ntype: " + name +
                                       "\ndimension: 3\nsizes: 2 2 2\nendian: little\n"
                                       "encoding: raw\n\n" +
                                       data);
        EXPECT_EQ(read_nrrd(dir / "t.nrrd").dtype(), type) << name;
    }
}

// ================================================================ NRRD, errors

TEST(NrrdReaderErrors, TruncatedData) {
    TempDir dir;
    write_file(dir / "d.raw", std::string(50, '\0'));
    write_file(dir / "t.nhdr", kHeader443 + "encoding: raw\ndata file: d.raw\n");
    expect_error([&] { read_nrrd(dir / "t.nhdr"); }, dir / "t.nhdr",
                 {(dir / "d.raw").string(), "holds 50 bytes, expected 96"});
    write_file(dir / "a.nrrd", kHeader443 + "encoding: raw\n\n" + std::string(10, '\0'));
    expect_error([&] { read_nrrd(dir / "a.nrrd"); }, dir / "a.nrrd", {"holds", "of data"});
    write_file(dir / "g.nrrd", kHeader443 + "encoding: gzip\n\n" + gzip(std::string(90, '\0')));
    expect_error([&] { read_nrrd(dir / "g.nrrd"); }, dir / "g.nrrd", {"ends early", "expected 96"});
}

TEST(NrrdReaderErrors, WrongSizes) {
    TempDir dir;
    write_file(dir / "z.nrrd",
               "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 0 2 2\nencoding: raw\n\n" + std::string(8, 'a'));
    expect_error([&] { read_nrrd(dir / "z.nrrd"); }, dir / "z.nrrd", {"field 'sizes'", "0 2 2"});
    write_file(dir / "n.nrrd",
               "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2 2\nencoding: raw\n\n" + std::string(8, 'a'));
    expect_error([&] { read_nrrd(dir / "n.nrrd"); }, dir / "n.nrrd",
                 {"field 'sizes'", "3 positive integers"});
    write_file(dir / "m.nrrd", "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 256 -1 2\nencoding: raw\n\n");
    expect_error([&] { read_nrrd(dir / "m.nrrd"); }, dir / "m.nrrd", {"sizes", "256 -1"});
    write_file(dir / "o.nrrd",
               "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 1 8 8\nencoding: raw\n\n" + std::string(64, 'a'));
    expect_error([&] { read_nrrd(dir / "o.nrrd"); }, dir / "o.nrrd", {"sizes", "at least 2"});
    write_file(dir / "d.nrrd",
               "NRRD0004\ntype: uchar\ndimension: 2\nsizes: 8 8\nencoding: raw\n\n" + std::string(64, 'a'));
    expect_error([&] { read_nrrd(dir / "d.nrrd"); }, dir / "d.nrrd", {"dimension"});
}

TEST(NrrdReaderErrors, HugeHeaderFailsFastWithoutAllocating) {
    TempDir dir;
    const auto t0 = std::chrono::steady_clock::now();
    write_file(dir / "h.nrrd",
               "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 16384 16384 4096\nencoding: raw\n\n1234");
    expect_error([&] { read_nrrd(dir / "h.nrrd"); }, dir / "h.nrrd", {"sizes", "limit"});
    write_file(dir / "j.nrrd",
               "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2048 2048 2048\nencoding: raw\n\n1234");
    expect_error([&] { read_nrrd(dir / "j.nrrd"); }, dir / "j.nrrd", {"holds"});
    write_file(
        dir / "k.nrrd",
        "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 2048 2048 2048\nencoding: gzip\n\n" + gzip("1234"));
    expect_error([&] { read_nrrd(dir / "k.nrrd"); }, dir / "k.nrrd", {"too few"});
    write_file(dir / "l.nrrd",
               "NRRD0004\ntype: uchar\ndimension: 3\nsizes: 99999999999999999999 2 2\nencoding: raw\n\n");
    expect_error([&] { read_nrrd(dir / "l.nrrd"); }, dir / "l.nrrd", {"sizes"});
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
}

TEST(NrrdReaderErrors, UnknownAndUnsupportedFieldValues) {
    TempDir dir;
    const std::string data(96, '\0');
    write_file(dir / "e.nrrd", kHeader443 + "encoding: base64\n\n" + data);
    expect_error([&] { read_nrrd(dir / "e.nrrd"); }, dir / "e.nrrd", {"encoding", "base64"});
    write_file(dir / "b.nrrd", kHeader443 + "encoding: bzip2\n\n" + data);
    expect_error([&] { read_nrrd(dir / "b.nrrd"); }, dir / "b.nrrd", {"unsupported encoding"});
    write_file(dir / "t.nrrd",
               "NRRD0004\ntype: quaternion\ndimension: 3\nsizes: 4 4 3\nencoding: raw\n\n" + data);
    expect_error([&] { read_nrrd(dir / "t.nrrd"); }, dir / "t.nrrd", {"type", "quaternion"});
    write_file(dir / "l.nrrd",
               "NRRD0004\ntype: long long\ndimension: 3\nsizes: 2 2 2\nendian: little\nencoding: raw\n\n" +
                   std::string(64, '\0'));
    expect_error([&] { read_nrrd(dir / "l.nrrd"); }, dir / "l.nrrd", {"type", "unsupported"});
    write_file(dir / "s.nrrd", kHeader443 + "encoding: raw\nspacings: 1 x 1\n\n" + data);
    expect_error([&] { read_nrrd(dir / "s.nrrd"); }, dir / "s.nrrd", {"field 'spacings'", "1 x 1"});
    write_file(dir / "d.nrrd",
               kHeader443 + "encoding: raw\nspace directions: (1,0,0) (0,1) (0,0,1)\n\n" + data);
    expect_error([&] { read_nrrd(dir / "d.nrrd"); }, dir / "d.nrrd", {"space directions"});
    write_file(dir / "p.nrrd", kHeader443 + "encoding: raw\nspace: right-anterior-superior-time\n\n" + data);
    expect_error([&] { read_nrrd(dir / "p.nrrd"); }, dir / "p.nrrd", {"space", "unsupported"});
    write_file(dir / "n.nrrd", "NRRD0004\ntype: short\ndimension: 3\nsizes: 4 4 3\nencoding: raw\n\n" + data);
    expect_error([&] { read_nrrd(dir / "n.nrrd"); }, dir / "n.nrrd", {"endian"});
    write_file(dir / "m.nrrd", "NRRD0004\ntype: short\ndimension: 3\nencoding: raw\n\n" + data);
    expect_error([&] { read_nrrd(dir / "m.nrrd"); }, dir / "m.nrrd", {"missing required field 'sizes'"});
    write_file(dir / "v.nrrd", "NRRD0009\n" + kHeader443.substr(9) + "encoding: raw\n\n" + data);
    expect_error([&] { read_nrrd(dir / "v.nrrd"); }, dir / "v.nrrd", {"version"});
}

TEST(NrrdReaderErrors, MissingDataFileAndCorruptGzip) {
    TempDir dir;
    write_file(dir / "m.nhdr", kHeader443 + "encoding: raw\ndata file: nowhere.raw\n");
    expect_error([&] { read_nrrd(dir / "m.nhdr"); }, dir / "m.nhdr", {"nowhere.raw", "does not exist"});
    write_file(dir / "c.nrrd", kHeader443 + "encoding: gzip\n\n" + std::string(200, '\x55'));
    expect_error([&] { read_nrrd(dir / "c.nrrd"); }, dir / "c.nrrd", {"corrupt"});
    std::string z = gzip(std::string(96, '\0'));
    z[z.size() - 6] = static_cast<char>(z[z.size() - 6] ^ 0x40);  // break the CRC
    write_file(dir / "k.nrrd", kHeader443 + "encoding: gzip\n\n" + z);
    expect_error([&] { read_nrrd(dir / "k.nrrd"); }, dir / "k.nrrd", {"corrupt"});
    write_file(dir / "x.nrrd", kHeader443 + "encoding: raw\n");
    expect_error([&] { read_nrrd(dir / "x.nrrd"); }, dir / "x.nrrd", {"no data"});
}

TEST(NrrdReaderErrors, NaNAndInfInFloatData) {
    TempDir dir;
    std::vector<float> values(27, 1.0f);
    values[17] = std::numeric_limits<float>::quiet_NaN();
    write_file(dir / "n.nrrd",
               "NRRD0004\ntype: float\ndimension: 3\nsizes: 3 3 3\nendian: little\nencoding: raw\n\n" +
                   bytes_of(values));
    expect_error([&] { read_nrrd(dir / "n.nrrd"); }, dir / "n.nrrd", {"sample 17 is NaN"});
    std::vector<double> d(27, 2.0);
    d[3] = -std::numeric_limits<double>::infinity();
    write_file(dir / "i.nrrd",
               "NRRD0004\ntype: double\ndimension: 3\nsizes: 3 3 3\nendian: big\nencoding: raw\n\n" +
                   bytes_of(d, true));
    expect_error([&] { read_nrrd(dir / "i.nrrd"); }, dir / "i.nrrd", {"sample 3 is infinite"});
}

TEST(NrrdReaderErrors, MangledHeadersNeverCrash) {
    TempDir dir;
    const std::string good = kHeader443 +
                             "encoding: gzip\nspace: RAS\nspace directions: (1,0,0) (0,1,0) (0,0,1)\n"
                             "space origin: (1,2,3)\nbyte skip: 2\n\n" +
                             gzip("xx" + bytes_of(ramp<std::uint16_t>(48)));
    WarningCatcher quiet;
    std::uint32_t rng = 12345;
    for (int trial = 0; trial < 300; ++trial) {
        std::string s = good;
        if (trial < 150) {
            s.resize(static_cast<std::size_t>(trial) * good.size() / 150);
        } else {
            for (int k = 0; k < 3; ++k) {
                rng = rng * 1664525u + 1013904223u;
                s[rng % s.size()] = static_cast<char>(rng >> 24);
            }
        }
        write_file(dir / "m.nrrd", s);
        try {
            (void)read_nrrd(dir / "m.nrrd");
        } catch (const Error&) {
        }
    }
    SUCCEED();
}

// ================================================================ MetaImage

TEST(MetaImageReader, LocalCompressedWithMatrixAndOffset) {
    TempDir dir;
    const auto values = ramp<std::uint16_t>(48);
    const std::string z = zlib_compress(bytes_of(values, true));
    write_file(dir / "m.mha",
               "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = True\n"
               "CompressedData = True\nCompressedDataSize = " +
                   std::to_string(z.size()) +
                   "\nTransformMatrix = 0 1 0 -1 0 0 0 0 1\nOffset = 5 6 7\n"
                   "CenterOfRotation = 0 0 0\nAnatomicalOrientation = RAI\nElementSpacing = 0.5 2 3\n"
                   "DimSize = 4 4 3\nSomeVendorField = whatever\nElementType = MET_USHORT\n"
                   "ElementDataFile = LOCAL\n" +
                   z);
    const Volume v = read_metaimage(dir / "m.mha");
    EXPECT_EQ(volume_u16(v), values);
    // axis 0 steps along +y (first three numbers), axis 1 along -x
    EXPECT_EQ(v.axes().column(0), (Vec3{0, 0.5, 0}));
    EXPECT_EQ(v.axes().column(1), (Vec3{-2, 0, 0}));
    EXPECT_EQ(v.axes().column(2), (Vec3{0, 0, 3}));
    EXPECT_EQ(v.origin(), (Vec3{5, 6, 7}));
}

TEST(MetaImageReader, DetachedListPatternAsciiAndHeaderSize) {
    TempDir dir;
    const auto values = ramp<std::int16_t>(48, 100, -50);
    const std::string bytes = bytes_of(values);
    for (int k = 0; k < 3; ++k)
        write_file(dir / ("s" + std::to_string(k) + ".raw"),
                   bytes.substr(static_cast<std::size_t>(k) * 32, 32));
    write_file(dir / "l.mhd",
               "NDims = 3\nDimSize = 4 4 3\nElementType = MET_SHORT\nElementDataFile = "
               "LIST\ns0.raw\ns1.raw\ns2.raw\n");
    EXPECT_EQ(read_metaimage(dir / "l.mhd").value(3, 3, 2), values[47]);
    write_file(dir / "p.mhd",
               "NDims = 3\nDimSize = 4 4 3\nElementType = MET_SHORT\nElementDataFile = s%d.raw 0 2 1\n");
    EXPECT_EQ(read_metaimage(dir / "p.mhd").value(1, 2, 1), values[1 + 4 * (2 + 4 * 1)]);
    write_file(dir / "h.raw", "HEADER" + bytes);
    write_file(
        dir / "h.mhd",
        "NDims = 3\nDimSize = 4 4 3\nHeaderSize = 6\nElementType = MET_SHORT\nElementDataFile = h.raw\n");
    EXPECT_EQ(read_metaimage(dir / "h.mhd").value(0, 0, 0), -50);
    write_file(
        dir / "e.mhd",
        "NDims = 3\nDimSize = 4 4 3\nHeaderSize = -1\nElementType = MET_SHORT\nElementDataFile = h.raw\n");
    EXPECT_EQ(read_metaimage(dir / "e.mhd").value(0, 0, 0), -50);
    write_file(dir / "a.mha",
               "NDims = 3\nDimSize = 2 2 2\nBinaryData = False\nElementType = MET_FLOAT\n"
               "ElementDataFile = LOCAL\n1 2 3 4\n5 6 7 8.5\n");
    EXPECT_DOUBLE_EQ(read_metaimage(dir / "a.mha").value(1, 1, 1), 8.5);
}

TEST(MetaImageReader, RgbChannels) {
    TempDir dir;
    write_file(dir / "c.mha",
               "ObjectType = Image\nNDims = 3\nDimSize = 2 2 2\nElementNumberOfChannels = 3\n"
               "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
                   bytes_of(ramp<std::uint8_t>(24)));
    const Volume v = read_metaimage(dir / "c.mha");
    EXPECT_EQ(v.components(), 3);
    EXPECT_EQ(v.value(1, 1, 1, 2), 23);
}

TEST(MetaImageReaderErrors, MissingFieldsAndBadValues) {
    TempDir dir;
    write_file(dir / "d.raw", std::string(96, '\0'));
    write_file(dir / "a.mhd",
               "ObjectType = Image\nNDims = 3\nElementType = MET_USHORT\nElementDataFile = d.raw\n");
    expect_error([&] { read_metaimage(dir / "a.mhd"); }, dir / "a.mhd", {"missing required field 'DimSize'"});
    write_file(dir / "b.mhd", "NDims = 3\nDimSize = 4 4 3\nElementType = MET_USHORT\n");
    expect_error([&] { read_metaimage(dir / "b.mhd"); }, dir / "b.mhd", {"ElementDataFile"});
    write_file(dir / "c.mhd",
               "NDims = 3\nDimSize = 4 4 3\nElementType = MET_COMPLEX\nElementDataFile = d.raw\n");
    expect_error([&] { read_metaimage(dir / "c.mhd"); }, dir / "c.mhd", {"ElementType", "MET_COMPLEX"});
    write_file(dir / "e.mhd", "NDims = 2\nDimSize = 4 4\nElementType = MET_UCHAR\nElementDataFile = d.raw\n");
    expect_error([&] { read_metaimage(dir / "e.mhd"); }, dir / "e.mhd", {"NDims"});
    write_file(dir / "f.mhd",
               "NDims = 3\nDimSize = 4 4 3\nElementSpacing = 1 x 1\nElementType = "
               "MET_USHORT\nElementDataFile = d.raw\n");
    expect_error([&] { read_metaimage(dir / "f.mhd"); }, dir / "f.mhd", {"ElementSpacing", "1 x 1"});
    write_file(dir / "g.mhd",
               "NDims = 3\nDimSize = 4 4 4\nElementType = MET_USHORT\nElementDataFile = d.raw\n");
    expect_error([&] { read_metaimage(dir / "g.mhd"); }, dir / "g.mhd",
                 {"d.raw", "holds 96 bytes, expected 128"});
    write_file(dir / "h.mhd",
               "NDims = 3\nDimSize = 4 4 3\nElementType = MET_USHORT\nElementDataFile = gone.raw\n");
    expect_error([&] { read_metaimage(dir / "h.mhd"); }, dir / "h.mhd", {"gone.raw", "does not exist"});
    write_file(dir / "i.mha",
               "NDims = 3\nDimSize = 4 4 3\nCompressedData = True\nElementType = MET_USHORT\n"
               "ElementDataFile = LOCAL\nnot zlib at all, not zlib at all, not zlib at all");
    expect_error([&] { read_metaimage(dir / "i.mha"); }, dir / "i.mha", {"corrupt"});
    write_file(dir / "j.mhd",
               "NDims = 3\nDimSize = 4 4 3\nElementType = MET_USHORT\nElementNumberOfChannels = 2\n"
               "ElementDataFile = d.raw\n");
    expect_error([&] { read_metaimage(dir / "j.mhd"); }, dir / "j.mhd", {"ElementNumberOfChannels"});
}

// ================================================================ read_volume

TEST(ReaderDetect, ByContentThenExtensionThenName) {
    TempDir dir;
    const auto values = ramp<std::uint16_t>(48);
    write_file(dir / "noext", kHeader443 + "encoding: raw\n\n" + bytes_of(values));
    EXPECT_EQ(volume_u16(read_volume(dir / "noext")), values);
    write_file(dir / "meta.dat",
               "ObjectType = Image\nNDims = 3\nDimSize = 4 4 3\nElementType = MET_USHORT\n"
               "ElementDataFile = LOCAL\n" +
                   bytes_of(values));
    EXPECT_EQ(volume_u16(read_volume(dir / "meta.dat")), values);
    write_file(dir / "vol_4x4x3_uint16.raw", bytes_of(values));
    EXPECT_EQ(volume_u16(read_volume(dir / "vol_4x4x3_uint16.raw")), values);
    write_file(dir / "vol_4x4x3_uint16.bin", bytes_of(values));
    EXPECT_EQ(volume_u16(read_volume(dir / "vol_4x4x3_uint16.bin")), values);
    write_file(dir / "bad.nhdr", "this is not a nrrd\n");
    expect_error([&] { read_volume(dir / "bad.nhdr"); }, dir / "bad.nhdr", {"not a NRRD file"});
}

TEST(ReaderDetect, ClearErrors) {
    TempDir dir;
    std::string garbage(1000, '\0');
    for (std::size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<char>((i * 7919u) >> 3);
    write_file(dir / "garbage.bin", garbage);
    expect_error([&] { read_volume(dir / "garbage.bin"); }, dir / "garbage.bin",
                 {"unrecognised volume format", "NRRD", "MetaImage"});
    write_file(dir / "empty.nrrd", "");
    expect_error([&] { read_volume(dir / "empty.nrrd"); }, dir / "empty.nrrd", {"empty"});
    write_file(dir / "plain.raw", garbage);
    expect_error([&] { read_volume(dir / "plain.raw"); }, dir / "plain.raw", {"NAME_XxYxZ_TYPE.raw"});
    expect_error([&] { read_volume(dir / "absent.nrrd"); }, dir / "absent.nrrd", {"does not exist"});
    expect_error([&] { read_volume(dir.path()); }, dir.path(), {"no DICOM files in folder"});
}

// ================================================================ shared data

TEST(ReaderShared, Lidc2NrrdRawAndNamedRawAgree) {
    FATHOM_REQUIRE_SHARED("ct_chest_lidc2/lidc2.nhdr");
    const auto dir = fathom::test::shared_data() / "ct_chest_lidc2";
    const Volume a = read_nrrd(dir / "lidc2.nhdr");
    EXPECT_EQ(a.dims(), (std::array<std::int64_t, 3>{256, 256, 133}));
    EXPECT_EQ(a.dtype(), DType::u8);
    EXPECT_DOUBLE_EQ(a.spacing().x, 1.40625);
    EXPECT_DOUBLE_EQ(a.spacing().y, 1.40625);
    EXPECT_DOUBLE_EQ(a.spacing().z, 2.5);
    EXPECT_EQ(a.value_range(), (std::array<double, 2>{0, 255}));
    RawLayout layout;
    layout.dims = {256, 256, 133};
    const Volume b = read_raw(dir / "lidc2_256x256x133_uint8.raw", layout);
    const auto inferred = infer_raw_layout(dir / "lidc2_256x256x133_uint8.raw");
    ASSERT_TRUE(inferred);
    const Volume c = read_volume(dir / "lidc2_256x256x133_uint8.raw");
    ASSERT_EQ(b.size_bytes(), a.size_bytes());
    ASSERT_EQ(c.size_bytes(), a.size_bytes());
    EXPECT_EQ(std::memcmp(a.bytes(), b.bytes(), a.size_bytes()), 0);
    EXPECT_EQ(std::memcmp(a.bytes(), c.bytes(), a.size_bytes()), 0);
}

TEST(ReaderShared, CtHeadIsBigEndian) {
    FATHOM_REQUIRE_SHARED("ct_head_stanford/cthead.nhdr");
    const Volume v = read_volume(fathom::test::shared_data() / "ct_head_stanford/cthead.nhdr");
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{256, 256, 113}));
    EXPECT_EQ(v.dtype(), DType::u16);
    EXPECT_EQ(v.value_range()[0], 0);
    EXPECT_EQ(v.value_range()[1], 3272);  // 65291 if read little-endian
    EXPECT_DOUBLE_EQ(v.spacing().z, 2.0);
}

TEST(ReaderShared, BunnyLargeGzipInt16) {
    FATHOM_REQUIRE_SHARED("ct_bunny_stanford/bunny.nhdr");
    const Volume v = read_nrrd(fathom::test::shared_data() / "ct_bunny_stanford/bunny.nhdr");
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{512, 512, 361}));
    EXPECT_EQ(v.dtype(), DType::i16);
    const auto range = v.value_range();
    EXPECT_EQ(range[0], -2000);
    EXPECT_LE(range[1], 4095);
    EXPECT_GT(range[1], 1000);
    EXPECT_DOUBLE_EQ(v.spacing().x, 0.337891);
    EXPECT_DOUBLE_EQ(v.spacing().z, 0.5);
}

TEST(ReaderShared, HeadsqMultiFilePattern) {
    FATHOM_REQUIRE_SHARED("sim_and_small_vtkdata/headsq/quarter.nhdr");
    const Volume v = read_volume(fathom::test::shared_data() / "sim_and_small_vtkdata/headsq/quarter.nhdr");
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{64, 64, 93}));
    EXPECT_EQ(v.dtype(), DType::i16);
    EXPECT_EQ(v.spacing(), (Vec3{3.2, 3.2, 1.5}));
    EXPECT_EQ(v.value_range(), (std::array<double, 2>{0, 3926}));
    EXPECT_EQ(v.value(32, 32, 50), 872);
}

TEST(ReaderShared, MetaImageMatchesNrrd) {
    FATHOM_REQUIRE_SHARED("ct_chest_lidc2/lidc2.nhdr");
    const auto dir = fathom::test::shared_data() / "ct_chest_lidc2";
    const Volume ref = read_nrrd(dir / "lidc2.nhdr");
    TempDir tmp;
    write_file(tmp / "lidc2.mhd",
               "ObjectType = Image\nNDims = 3\nBinaryData = True\nBinaryDataByteOrderMSB = False\n"
               "CompressedData = False\nTransformMatrix = 1 0 0 0 1 0 0 0 1\nOffset = 0 0 0\n"
               "ElementSpacing = 1.40625 1.40625 2.5\nDimSize = 256 256 133\n"
               "ElementType = MET_UCHAR\nElementDataFile = " +
                   fs::absolute(dir / "lidc2_256x256x133_uint8.raw").string() + "\n");
    const Volume a = read_volume(tmp / "lidc2.mhd");
    const std::string raw(reinterpret_cast<const char*>(ref.bytes()), ref.size_bytes());
    write_file(tmp / "lidc2.mha",
               "ObjectType = Image\nNDims = 3\nDimSize = 256 256 133\n"
               "ElementSpacing = 1.40625 1.40625 2.5\nCompressedData = True\n"
               "ElementType = MET_UCHAR\nElementDataFile = LOCAL\n" +
                   zlib_compress(raw));
    const Volume b = read_volume(tmp / "lidc2.mha");
    for (const Volume* v : {&a, &b}) {
        ASSERT_EQ(v->size_bytes(), ref.size_bytes());
        EXPECT_EQ(std::memcmp(v->bytes(), ref.bytes(), ref.size_bytes()), 0);
        EXPECT_EQ(v->spacing(), ref.spacing());
        EXPECT_EQ(v->origin(), ref.origin());
    }
}

// ================================================================ describe_volume

TEST(InfoDescribe, ShowsDimsTypeAndHistogram) {
    Volume v({4, 3, 2}, DType::u16);
    for (int k = 0; k < 2; ++k)
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 4; ++i) v.set_value(i, j, k, i * 100 + j * 10 + k);
    v.set_spacing({0.5, 1, 2});
    const std::string text = describe_volume(v, "x.nrrd");
    EXPECT_NE(text.find("x.nrrd"), std::string::npos) << text;
    EXPECT_NE(text.find("4 x 3 x 2"), std::string::npos) << text;
    EXPECT_NE(text.find("uint16"), std::string::npos) << text;
    EXPECT_NE(text.find("0.5 x 1 x 2"), std::string::npos) << text;
    EXPECT_NE(text.find("0 .. 321"), std::string::npos) << text;
    EXPECT_NE(text.find("histogram"), std::string::npos) << text;
    EXPECT_NE(text.find('#'), std::string::npos) << text;
    EXPECT_EQ(text.find("directions"), std::string::npos) << text;
    std::size_t lines = 0, start = 0;
    for (std::size_t nl; (nl = text.find('\n', start)) != std::string::npos; start = nl + 1, ++lines)
        EXPECT_LE(nl - start, 80u) << text.substr(start, nl - start);
    EXPECT_GE(lines, 16u + 9u);
}

TEST(InfoDescribe, ShowsDirectionsWhenRotatedAndHandlesConstantVolumes) {
    Volume v({2, 2, 2}, DType::f32);
    v.set_axes(Mat3::from_columns({0, 1, 0}, {-1, 0, 0}, {0, 0, 1}));
    const std::string text = describe_volume(v, "r.mha");
    EXPECT_NE(text.find("directions"), std::string::npos) << text;
    EXPECT_NE(text.find("every sample is 0"), std::string::npos) << text;
}
