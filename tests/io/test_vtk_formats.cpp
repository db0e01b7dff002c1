// SLC, legacy VTK and VTK XML ImageData readers (docs/formats.md): exact
// values and axis order on small files written here, the shared real files,
// and clear errors (naming the file) for malformed input.
#include <algorithm>
#include <bit>
#include <chrono>
#include <cmath>
#include <cstdio>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <functional>
#include <limits>
#include <sstream>
#include <string>
#include <vector>

#include <gtest/gtest.h>
#include <zlib.h>

#include "fathom/error.h"
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

/// Samples as bytes in the requested byte order.
template <class T>
std::string bytes_of(const std::vector<T>& values, bool big_endian = false) {
    std::string out(values.size() * sizeof(T), '\0');
    std::memcpy(out.data(), values.data(), out.size());
    if (big_endian != (std::endian::native == std::endian::big))
        for (std::size_t i = 0; i < out.size(); i += sizeof(T))
            std::reverse(out.begin() + static_cast<std::ptrdiff_t>(i),
                         out.begin() + static_cast<std::ptrdiff_t>(i + sizeof(T)));
    return out;
}

std::string zlib_compress(const std::string& data) {
    uLongf n = compressBound(data.size());
    std::string out(n, '\0');
    EXPECT_EQ(compress(reinterpret_cast<Bytef*>(out.data()), &n, reinterpret_cast<const Bytef*>(data.data()),
                       data.size()),
              Z_OK);
    out.resize(n);
    return out;
}

std::string base64(const std::string& data) {
    static constexpr char kAlphabet[] = "ABCDEFGHIJKLMNOPQRSTUVWXYZabcdefghijklmnopqrstuvwxyz0123456789+/";
    std::string out;
    for (std::size_t i = 0; i < data.size(); i += 3) {
        const std::size_t n = std::min<std::size_t>(3, data.size() - i);
        std::uint32_t bits = 0;
        for (std::size_t k = 0; k < 3; ++k)
            bits = (bits << 8) | (k < n ? static_cast<unsigned char>(data[i + k]) : 0u);
        for (std::size_t k = 0; k < 4; ++k) out += k <= n ? kAlphabet[(bits >> (18 - 6 * k)) & 63u] : '=';
    }
    return out;
}

/// Reads the file: either a volume or a fathom::Error naming the file, never anything else.
void read_or_error(const std::function<Volume(const fs::path&)>& reader, const fs::path& file) {
    try {
        (void)reader(file);
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find(file.string()), std::string::npos) << e.what();
    }
}

class WarningCatcher {
public:
    WarningCatcher() : previous_(set_warning_sink([this](const std::string& m) { messages.push_back(m); })) {}
    ~WarningCatcher() { set_warning_sink(previous_); }
    WarningCatcher(const WarningCatcher&) = delete;
    WarningCatcher& operator=(const WarningCatcher&) = delete;
    [[nodiscard]] bool any(const std::string& word) const {
        return std::any_of(messages.begin(), messages.end(),
                           [&](const std::string& m) { return m.find(word) != std::string::npos; });
    }
    std::vector<std::string> messages;

private:
    WarningSink previous_;
};

using Dims = std::array<std::int64_t, 3>;

/// Value at node (i, j, k) of the small test grids.
double node_value(std::int64_t i, std::int64_t j, std::int64_t k) {
    return static_cast<double>(i + 10 * j + 50 * k);
}

template <class T>
std::vector<T> grid_values(const Dims& d, double scale = 1, double offset = 0) {
    std::vector<T> v;
    for (std::int64_t k = 0; k < d[2]; ++k)
        for (std::int64_t j = 0; j < d[1]; ++j)
            for (std::int64_t i = 0; i < d[0]; ++i)
                v.push_back(static_cast<T>(node_value(i, j, k) * scale + offset));
    return v;
}

void expect_grid(const Volume& v, const Dims& d, double scale = 1, double offset = 0) {
    ASSERT_EQ(v.dims(), d);
    for (std::int64_t k = 0; k < d[2]; ++k)
        for (std::int64_t j = 0; j < d[1]; ++j)
            for (std::int64_t i = 0; i < d[0]; ++i)
                ASSERT_EQ(v.value(i, j, k), node_value(i, j, k) * scale + offset)
                    << i << " " << j << " " << k;
}

/// Min, max and sum over all samples.
struct Stats {
    double min, max, sum;
};
Stats stats(const Volume& v) {
    Stats s{std::numeric_limits<double>::infinity(), -std::numeric_limits<double>::infinity(), 0};
    const std::int64_t n = v.num_nodes() * v.components();
    for (std::int64_t i = 0; i < n; ++i) {
        const double x = v.value_linear(i);
        s.min = std::min(s.min, x);
        s.max = std::max(s.max, x);
        s.sum += x;
    }
    return s;
}

// ---------------------------------------------------------------- SLC files

/// VolVis 8-bit run-length code of one slice (runs of 3 or more repeat, the rest literal), then 0.
std::string rle(const std::vector<std::uint8_t>& s) {
    std::string out;
    std::size_t i = 0;
    while (i < s.size()) {
        std::size_t run = 1;
        while (i + run < s.size() && s[i + run] == s[i] && run < 127) ++run;
        if (run >= 3) {
            out += static_cast<char>(run);
            out += static_cast<char>(s[i]);
            i += run;
            continue;
        }
        std::size_t lit = 0;
        while (i + lit < s.size() && lit < 127) {
            if (i + lit + 2 < s.size() && s[i + lit] == s[i + lit + 1] && s[i + lit] == s[i + lit + 2]) break;
            ++lit;
        }
        out += static_cast<char>(0x80 | lit);
        out.append(reinterpret_cast<const char*>(s.data() + i), lit);
        i += lit;
    }
    out += '\0';
    return out;
}

std::string slc_header(const Dims& d, int compression, const std::string& spacing = "0.5 2 3") {
    std::string h = "11111\n" + std::to_string(d[0]) + " " + std::to_string(d[1]) + " " +
                    std::to_string(d[2]) + " 8\n" + spacing + "\n1 6 0 " + std::to_string(compression) +
                    "\n2 2 X";
    h.append(12, '\x07');  // a 2 x 2 icon, three planes
    return h;
}

/// An SLC file of grid_values; `drop` samples are cut from the end of each slice's code.
std::string slc_file(const Dims& d, int compression, std::size_t drop = 0) {
    const auto values = grid_values<std::uint8_t>(d);
    std::string out = slc_header(d, compression);
    const auto plane = static_cast<std::size_t>(d[0] * d[1]);
    for (std::int64_t k = 0; k < d[2]; ++k) {
        std::vector<std::uint8_t> slice(values.begin() + static_cast<std::ptrdiff_t>(k * d[0] * d[1]),
                                        values.begin() + static_cast<std::ptrdiff_t>((k + 1) * d[0] * d[1]));
        if (compression == 0) {
            out.append(reinterpret_cast<const char*>(slice.data()), slice.size());
            continue;
        }
        slice.resize(plane - drop);
        const std::string code = rle(slice);
        out += std::to_string(code.size()) + " X" + code;
    }
    return out;
}

// ---------------------------------------------------------------- legacy VTK files

std::string vtk_header(const std::string& format, const Dims& d, const std::string& type,
                       const std::string& extra = "SPACING 0.5 2 3\nORIGIN -1 2 3.5\n") {
    return "# vtk DataFile Version 3.0\na test volume\n" + format +
           "\nDATASET STRUCTURED_POINTS\nDIMENSIONS " + std::to_string(d[0]) + " " + std::to_string(d[1]) +
           " " + std::to_string(d[2]) + "\n" + extra + "POINT_DATA " + std::to_string(d[0] * d[1] * d[2]) +
           "\nSCALARS values " + type + "\nLOOKUP_TABLE default\n";
}

// ---------------------------------------------------------------- VTK XML files

struct VtiOptions {
    std::string file_attrs = R"(byte_order="LittleEndian" header_type="UInt32")";
    std::string image_attrs = R"(WholeExtent="0 4 0 3 0 2" Origin="0 0 0" Spacing="1 1 1")";
    std::string extent = "0 4 0 3 0 2";
    std::string point_data_attrs;
    std::string arrays;    // <DataArray> elements
    std::string appended;  // the AppendedData element, if any
};

std::string vti(const VtiOptions& o) {
    return "<?xml version=\"1.0\"?>\n<VTKFile type=\"ImageData\" version=\"1.0\" " + o.file_attrs +
           ">\n  <ImageData " + o.image_attrs + ">\n    <Piece Extent=\"" + o.extent +
           "\">\n      <PointData " + o.point_data_attrs + ">\n" + o.arrays +
           "      </PointData>\n      <CellData>\n      </CellData>\n" + "    </Piece>\n  </ImageData>\n" +
           o.appended + "</VTKFile>\n";
}

std::string u32(std::uint32_t v, bool big = false) {
    return bytes_of(std::vector<std::uint32_t>{v}, big);
}
std::string u64(std::uint64_t v, bool big = false) {
    return bytes_of(std::vector<std::uint64_t>{v}, big);
}

/// A vtkZLibDataCompressor block set: header (UInt32 or UInt64) and the compressed blocks.
std::pair<std::string, std::string> zlib_blocks(const std::string& data, std::size_t block, bool wide,
                                                bool big = false) {
    std::vector<std::string> blocks;
    for (std::size_t i = 0; i < data.size(); i += block)
        blocks.push_back(zlib_compress(data.substr(i, block)));
    const auto num = [&](std::uint64_t v) {
        return wide ? u64(v, big) : u32(static_cast<std::uint32_t>(v), big);
    };
    std::string header = num(blocks.size()) + num(block) + num(data.size() % block);
    std::string body;
    for (const auto& b : blocks) {
        header += num(b.size());
        body += b;
    }
    return {header, body};
}

const Dims kDims{5, 4, 3};

}  // namespace

// ================================================================ SLC

TEST(SlcReader, RunLengthAndRawSlicesXFastest) {
    TempDir dir;
    for (int compression : {1, 0}) {
        const fs::path p = dir / ("v" + std::to_string(compression) + ".slc");
        write_file(p, slc_file(kDims, compression));
        WarningCatcher w;
        const Volume v = read_slc(p);
        EXPECT_TRUE(w.messages.empty()) << w.messages.front();
        EXPECT_EQ(v.dtype(), DType::u8);
        EXPECT_EQ(v.components(), 1);
        EXPECT_EQ(v.spacing(), (Vec3{0.5, 2, 3}));
        EXPECT_EQ(v.origin(), (Vec3{0, 0, 0}));
        expect_grid(v, kDims);
        expect_grid(read_volume(p), kDims);
    }
    // by content without the extension, and long runs (> 127) in big flat slices
    write_file(dir / "noext", slc_file(kDims, 1));
    expect_grid(read_volume(dir / "noext"), kDims);
    std::string flat = slc_header({300, 2, 2}, 1, "1 1 1");
    for (int k = 0; k < 2; ++k) {
        const std::string code = rle(std::vector<std::uint8_t>(600, static_cast<std::uint8_t>(9 + k)));
        flat += "\n" + std::to_string(code.size()) + " X" + code;
    }
    write_file(dir / "flat.slc", flat);
    const Volume f = read_slc(dir / "flat.slc");
    EXPECT_EQ(f.value(299, 1, 0), 9);
    EXPECT_EQ(f.value(0, 0, 1), 10);
    EXPECT_EQ(f.value_range(), (std::array<double, 2>{9, 10}));
}

TEST(SlcReader, ShortSlicesArePaddedWithZeroAndReported) {
    TempDir dir;
    const fs::path p = dir / "short.slc";
    write_file(p, slc_file(kDims, 1, 1));  // every slice decodes one sample short, as embryo.slc does
    WarningCatcher w;
    const Volume v = read_slc(p);
    ASSERT_EQ(w.messages.size(), 1u);
    EXPECT_NE(w.messages[0].find("3 of 3 slices decode short"), std::string::npos) << w.messages[0];
    EXPECT_NE(w.messages[0].find(p.string()), std::string::npos);
    for (std::int64_t k = 0; k < 3; ++k)
        for (std::int64_t j = 0; j < 4; ++j)
            for (std::int64_t i = 0; i < 5; ++i)
                EXPECT_EQ(v.value(i, j, k), i == 4 && j == 3 ? 0.0 : node_value(i, j, k));
    // a whole row short is still the quirk; more is corrupt
    write_file(p, slc_file(kDims, 1, 5));
    EXPECT_EQ(read_slc(p).value(0, 3, 2), 0.0);
    write_file(p, slc_file(kDims, 1, 6));
    expect_error([&] { read_slc(p); }, p, {"slice 0 decodes to 14 samples, expected 20", "corrupt"});
}

TEST(SlcReaderErrors, BadHeaders) {
    TempDir dir;
    const fs::path p = dir / "bad.slc";
    const auto expect = [&](const std::string& text, const std::vector<std::string>& words) {
        write_file(p, text);
        expect_error([&] { read_slc(p); }, p, words);
    };
    std::string good = slc_file(kDims, 1);
    expect("11112\n" + good.substr(6), {"not an SLC file", "11111"});
    expect("11111\n5 4 3 16\n1 1 1\n1 6 0 1\n2 2 X" + std::string(12, '\0'), {"bits per voxel", "16"});
    expect("11111\n5 4 3 8\n1 1 1\n1 6 0 2\n2 2 X" + std::string(12, '\0'), {"compression", "2"});
    expect("11111\n5 4 3 8\n1 0 1\n1 6 0 1\n2 2 X" + std::string(12, '\0'), {"y spacing", "non-zero"});
    expect("11111\n5 4 3 8\n1 1 1\n1 6 0 1\n2 2 Y", {"'X'"});
    expect("11111\n5 4", {"ends before", "z size"});
    expect("11111\n5 -4 3 8\n1 1 1\n1 6 0 1\n2 2 X", {"y size"});
    expect("11111\n5 1 3 8\n1 1 1\n1 6 0 1\n2 2 X" + std::string(12, '\0'), {"axis 1 has 1 samples"});
    expect("11111\n5 4 3 8\n1 1 1\n1 6 0 1\n100 100 X" + std::string(500, '\0'), {"icon", "truncated"});
}

TEST(SlcReaderErrors, TruncatedAndCorruptSlices) {
    TempDir dir;
    const fs::path p = dir / "t.slc";
    const std::string good = slc_file(kDims, 1);
    write_file(p, good.substr(0, good.size() - 7));
    expect_error([&] { read_slc(p); }, p, {"truncated"});
    const std::string raw = slc_file(kDims, 0);
    write_file(p, raw.substr(0, raw.size() - 1));
    expect_error([&] { read_slc(p); }, p, {"truncated"});

    const std::string head = slc_header(kDims, 1);
    const auto with_slices = [&](const std::string& first) {
        std::string s = head + first;
        for (int k = 1; k < 3; ++k) s += "3 X\x14\x01" + std::string(1, '\0');
        return s;
    };
    // 20 samples wanted; 21 decoded: overflow
    write_file(p, with_slices(std::string("3 X\x15\x01") + '\0'));
    expect_error([&] { read_slc(p); }, p, {"slice 0 decodes to more than its 20 samples"});
    // a literal run of 5 with only 2 bytes left in the slice's code
    write_file(p, with_slices("3 X\x85\x01\x02"));
    expect_error([&] { read_slc(p); }, p, {"slice 0", "goes past"});
    // a repeat run without its value
    write_file(p, with_slices("1 X\x14"));
    expect_error([&] { read_slc(p); }, p, {"slice 0", "goes past"});
    // no size field
    write_file(p, with_slices("abc"));
    expect_error([&] { read_slc(p); }, p, {"slice 0", "'N X'"});
    // a size larger than the file
    write_file(p, head + "999999 X" + std::string(40, '\x01'));
    expect_error([&] { read_slc(p); }, p, {"999999", "truncated"});
}

TEST(SlcReaderErrors, AbsurdDimensionsFailBeforeAllocating) {
    TempDir dir;
    const fs::path p = dir / "huge.slc";
    const auto t0 = std::chrono::steady_clock::now();
    write_file(p, "11111\n100000 100000 100000 8\n1 1 1\n1 6 0 1\n2 2 X" + std::string(12, '\0') +
                      "3 X\x14\x01" + '\0');
    expect_error([&] { read_slc(p); }, p, {"GiB limit"});
    // within the limit, but the file cannot hold it
    write_file(
        p, "11111\n2000 2000 2000 8\n1 1 1\n1 6 0 1\n2 2 X" + std::string(12, '\0') + "3 X\x14\x01" + '\0');
    expect_error([&] { read_slc(p); }, p, {"too few for 2000 slices"});
    write_file(p, "11111\n2000 2000 2000 8\n1 1 1\n1 6 0 0\n2 2 X" + std::string(12, '\0'));
    expect_error([&] { read_slc(p); }, p, {"too few"});
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);
}

TEST(SlcReaderErrors, MangledFilesNeverCrash) {
    TempDir dir;
    const fs::path p = dir / "m.slc";
    const std::string good = slc_file(kDims, 1);
    WarningCatcher quiet;
    for (std::size_t n = 0; n < good.size(); ++n) {
        write_file(p, good.substr(0, n));
        read_or_error(read_slc, p);
    }
    for (std::size_t i = 0; i < good.size(); ++i) {
        std::string bad = good;
        bad[i] = static_cast<char>(bad[i] ^ 0xa5);
        write_file(p, bad);
        read_or_error(read_slc, p);
    }
}

TEST(SlcShared, EmbryoShortSlices) {
    FATHOM_REQUIRE_SHARED("sim_and_small_vtkdata/embryo.slc");
    const fs::path p = fathom::test::shared_data() / "sim_and_small_vtkdata/embryo.slc";
    WarningCatcher w;
    const Volume v = read_volume(p);
    EXPECT_EQ(v.dims(), (Dims{256, 256, 256}));
    EXPECT_EQ(v.dtype(), DType::u8);
    EXPECT_EQ(v.spacing(), (Vec3{1, 1, 1}));
    EXPECT_EQ(v.origin(), (Vec3{0, 0, 0}));
    const Stats s = stats(v);
    EXPECT_EQ(s.min, 0);
    EXPECT_EQ(s.max, 197);
    EXPECT_EQ(s.sum, 63724611);
    EXPECT_EQ(v.value_range(), (std::array<double, 2>{0, 197}));
    EXPECT_EQ(v.value(128, 128, 128), 19);
    EXPECT_EQ(v.value(255, 255, 0), 0);  // the sample each slice lacks
    ASSERT_EQ(w.messages.size(), 1u);
    EXPECT_TRUE(w.any("256 of 256 slices decode short (by up to 1 sample)")) << w.messages[0];
}

TEST(SlcShared, Neghip) {
    FATHOM_REQUIRE_SHARED("sim_and_small_vtkdata/neghip.slc");
    const fs::path p = fathom::test::shared_data() / "sim_and_small_vtkdata/neghip.slc";
    WarningCatcher w;
    const Volume v = read_slc(p);
    EXPECT_TRUE(w.messages.empty());
    EXPECT_EQ(v.dims(), (Dims{66, 66, 66}));
    EXPECT_EQ(v.dtype(), DType::u8);
    EXPECT_EQ(v.spacing(), (Vec3{1, 1, 1}));
    EXPECT_EQ(v.origin(), (Vec3{0, 0, 0}));
    const Stats s = stats(v);
    EXPECT_EQ(s.min, 0);
    EXPECT_EQ(s.max, 255);
    EXPECT_EQ(s.sum, 4824177);
}

// ================================================================ legacy VTK

TEST(LegacyVtkReader, AsciiExactValuesAndPlacement) {
    TempDir dir;
    const fs::path p = dir / "a.vtk";
    const auto values = grid_values<float>(kDims, 0.25, -3);
    std::ostringstream text;
    text << vtk_header("ASCII", kDims, "float");
    for (std::size_t n = 0; n < values.size(); ++n) text << values[n] << (n % 7 == 6 ? "\n" : " ");
    write_file(p, text.str());
    const Volume v = read_legacy_vtk(p);
    EXPECT_EQ(v.dtype(), DType::f32);
    EXPECT_EQ(v.spacing(), (Vec3{0.5, 2, 3}));
    EXPECT_EQ(v.origin(), (Vec3{-1, 2, 3.5}));
    expect_grid(v, kDims, 0.25, -3);

    // lower-case keywords, CRLF lines, a blank line before the format, keywords in another order,
    // ASPECT_RATIO, an explicit 1 component
    std::string crlf =
        "# vtk DataFile Version 2.0\r\ntitle\r\n\r\nascii\r\ndataset structured_points\r\n"
        "origin 1 1 1\r\naspect_ratio 2 2 2\r\ndimensions 2 2 2\r\npoint_data 8\r\n"
        "scalars s short 1\r\nlookup_table default\r\n-1 2 -3 4\r\n5 -6 7 -8\r\n";
    write_file(dir / "b.dat", crlf);
    const Volume b = read_volume(dir / "b.dat");  // by content
    EXPECT_EQ(b.dtype(), DType::i16);
    EXPECT_EQ(b.spacing(), (Vec3{2, 2, 2}));
    EXPECT_EQ(b.origin(), (Vec3{1, 1, 1}));
    EXPECT_EQ(b.value(1, 0, 0), 2);
    EXPECT_EQ(b.value(0, 1, 0), -3);
    EXPECT_EQ(b.value(1, 1, 1), -8);
}

template <class T>
void check_binary_type(const TempDir& dir, const std::string& vtk_type, DType dtype) {
    const fs::path p = dir / ("t_" + vtk_type + ".vtk");
    const double offset = std::is_signed_v<T> ? -60 : 0;
    write_file(
        p, vtk_header("BINARY", kDims, vtk_type) + bytes_of(grid_values<T>(kDims, 1, offset), true) + "\n");
    WarningCatcher w;
    const Volume v = read_volume(p);
    EXPECT_TRUE(w.messages.empty()) << vtk_type;
    EXPECT_EQ(v.dtype(), dtype) << vtk_type;
    expect_grid(v, kDims, 1, offset);
}

TEST(LegacyVtkReader, BinaryBigEndianEveryType) {
    TempDir dir;
    check_binary_type<std::uint8_t>(dir, "unsigned_char", DType::u8);
    check_binary_type<std::int8_t>(dir, "char", DType::i8);
    check_binary_type<std::int8_t>(dir, "signed_char", DType::i8);
    check_binary_type<std::uint16_t>(dir, "unsigned_short", DType::u16);
    check_binary_type<std::int16_t>(dir, "short", DType::i16);
    check_binary_type<std::uint32_t>(dir, "unsigned_int", DType::u32);
    check_binary_type<std::int32_t>(dir, "int", DType::i32);
    check_binary_type<float>(dir, "float", DType::f32);
    check_binary_type<double>(dir, "double", DType::f64);
}

TEST(LegacyVtkReader, BinaryDataStartRightAfterTheLookupTableLine) {
    TempDir dir;
    const fs::path p = dir / "ws.vtk";
    // samples that look like whitespace must not be skipped
    write_file(p, vtk_header("BINARY", {2, 2, 2}, "unsigned_char", "") + std::string("\n \r\tabcd"));
    const Volume v = read_legacy_vtk(p);
    EXPECT_EQ(v.value(0, 0, 0), 10);
    EXPECT_EQ(v.value(1, 0, 0), 32);
    EXPECT_EQ(v.value(0, 1, 0), 13);
    EXPECT_EQ(v.value(1, 1, 0), 9);
    EXPECT_EQ(v.value(1, 1, 1), 100);
}

TEST(LegacyVtkReader, TrailingDataAndDirection) {
    TempDir dir;
    const fs::path p = dir / "t.vtk";
    const std::string data = bytes_of(grid_values<std::int16_t>(kDims), true);
    // further attributes after the scalars: read, with a warning
    write_file(p, vtk_header("BINARY", kDims, "short") + data + "\nVECTORS v float\n1 2 3\n");
    {
        WarningCatcher w;
        expect_grid(read_legacy_vtk(p), kDims);
        EXPECT_TRUE(w.any("bytes after the scalars are ignored"))
            << (w.messages.empty() ? "" : w.messages[0]);
    }
    // a row-major DIRECTION: i steps along +y, j along -x
    write_file(p,
               vtk_header("BINARY", kDims, "short", "SPACING 1 2 3\nDIRECTION 0 -1 0 1 0 0 0 0 1\n") + data);
    const Volume v = read_legacy_vtk(p);
    EXPECT_EQ(v.index_to_world({1, 0, 0}), (Vec3{0, 1, 0}));
    EXPECT_EQ(v.index_to_world({0, 1, 0}), (Vec3{-2, 0, 0}));
    EXPECT_EQ(v.index_to_world({0, 0, 1}), (Vec3{0, 0, 3}));
}

TEST(LegacyVtkReaderErrors, HeadersTypesAndSizes) {
    TempDir dir;
    const fs::path p = dir / "e.vtk";
    const std::string data = bytes_of(grid_values<std::uint8_t>(kDims), true);
    const auto expect = [&](const std::string& text, const std::vector<std::string>& words) {
        write_file(p, text);
        expect_error([&] { read_legacy_vtk(p); }, p, words);
    };
    const std::string good = vtk_header("BINARY", kDims, "unsigned_char") + data;
    expect("# vtk DataFlie Version 3.0\n" + good.substr(good.find('\n') + 1), {"not a legacy VTK file"});
    expect("# vtk DataFile Version 3.0\nx\nHEX\nDATASET STRUCTURED_POINTS\n",
           {"after the title line", "ASCII or BINARY"});
    expect("# vtk DataFile Version 3.0\nx\nASCII\nDATASET POLYDATA\nPOINTS 3 float\n",
           {"POLYDATA", "unsupported"});
    expect(
        "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 5 4 3\nPOINT_DATA 61\n"
        "SCALARS v unsigned_char\nLOOKUP_TABLE default\n" +
            data,
        {"POINT_DATA 61", "60 points"});
    expect(vtk_header("BINARY", kDims, "vtktypeint64") + data, {"vtktypeint64", "unsupported"});
    expect(vtk_header("BINARY", kDims, "complex") + data, {"'complex' is unknown"});
    expect(vtk_header("BINARY", kDims, "float 3") + data, {"3 components are unsupported"});
    expect(
        "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 5 4 3\nPOINT_DATA 60\n"
        "VECTORS v float\n",
        {"VECTORS", "only SCALARS"});
    expect(
        "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET STRUCTURED_POINTS\nDIMENSIONS 5 4 3\nCELL_DATA 24\n",
        {"CELL_DATA", "unsupported"});
    expect(
        "# vtk DataFile Version 3.0\nx\nBINARY\nDATASET STRUCTURED_POINTS\nPOINT_DATA 60\n"
        "SCALARS v unsigned_char\nLOOKUP_TABLE default\n",
        {"missing keyword DIMENSIONS"});
    expect(vtk_header("BINARY", kDims, "unsigned_char", "SPACING 1 0 1\n") + data, {"SPACING", "non-zero"});
    expect(vtk_header("BINARY", kDims, "unsigned_char", "EXTENT 1 2 3\n") + data,
           {"unknown keyword 'extent'"});
    expect(vtk_header("BINARY", kDims, "unsigned_char").substr(0, 150), {"ends before the scalar data"});
    // wrong sizes and truncated data
    expect(good.substr(0, good.size() - 1), {"holds", "expected"});
    expect(vtk_header("ASCII", kDims, "unsigned_char") + "1 2 3\n" + std::string(80, ' '),
           {"holds 3 values, expected 60"});
    expect(vtk_header("ASCII", kDims, "unsigned_char") + std::string(60, '1') + " x", {"not a valid uint8"});
    expect(vtk_header("ASCII", kDims, "short", "") + "1 2 3 70000" + std::string(80, ' '),
           {"value 3 '70000' is not a valid int16"});
}

TEST(LegacyVtkReaderErrors, AbsurdDimensionsAndMangledFiles) {
    TempDir dir;
    const fs::path p = dir / "h.vtk";
    const auto t0 = std::chrono::steady_clock::now();
    write_file(p, vtk_header("BINARY", {100000, 100000, 100000}, "float") + "abc");
    expect_error([&] { read_legacy_vtk(p); }, p, {"GiB limit"});
    write_file(p, vtk_header("BINARY", {2000, 2000, 1000}, "float") + "abc");
    expect_error([&] { read_legacy_vtk(p); }, p, {"expected"});
    write_file(p, vtk_header("ASCII", {2000, 2000, 1000}, "float") + "1 2 3");
    expect_error([&] { read_legacy_vtk(p); }, p, {"too few"});
    EXPECT_LT(std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count(), 2.0);

    WarningCatcher quiet;
    for (const std::string& format : {std::string("BINARY"), std::string("ASCII")}) {
        std::string good = vtk_header(format, kDims, "short");
        if (format == "BINARY")
            good += bytes_of(grid_values<std::int16_t>(kDims), true);
        else
            for (auto x : grid_values<std::int16_t>(kDims)) good += std::to_string(x) + " ";
        for (std::size_t n = 0; n < good.size(); n += 3) {
            write_file(p, good.substr(0, n));
            read_or_error(read_legacy_vtk, p);
        }
        for (std::size_t i = 0; i < good.size(); i += 2) {
            std::string bad = good;
            bad[i] = static_cast<char>(bad[i] ^ 0x5a);
            write_file(p, bad);
            read_or_error(read_legacy_vtk, p);
        }
    }
}

TEST(LegacyVtkShared, IronProtTrailingByte) {
    FATHOM_REQUIRE_SHARED("sim_and_small_vtkdata/ironProt.vtk");
    const fs::path p = fathom::test::shared_data() / "sim_and_small_vtkdata/ironProt.vtk";
    WarningCatcher w;
    const Volume v = read_volume(p);
    EXPECT_TRUE(w.messages.empty()) << w.messages.front();  // the one trailing byte is a newline
    EXPECT_EQ(v.dims(), (Dims{68, 68, 68}));
    EXPECT_EQ(v.dtype(), DType::u8);
    EXPECT_EQ(v.spacing(), (Vec3{1, 1, 1}));
    EXPECT_EQ(v.origin(), (Vec3{0, 0, 0}));
    const Stats s = stats(v);
    EXPECT_EQ(s.min, 0);
    EXPECT_EQ(s.max, 255);
    EXPECT_EQ(s.sum, 4131089);
    EXPECT_EQ(v.value(34, 34, 34), 131);
}

// ================================================================ VTK XML ImageData

TEST(VtiReader, AsciiInlineExactValuesAndExtentOrigin) {
    TempDir dir;
    const fs::path p = dir / "a.vti";
    VtiOptions o;
    o.image_attrs = R"(WholeExtent="1 5 0 3 2 4" Origin="10 20 30" Spacing="0.5 1 2")";
    o.extent = "1 5 0 3 2 4";
    std::string values;
    for (auto x : grid_values<std::int16_t>(kDims, -1, 7)) values += std::to_string(x) + (x % 3 ? " " : "\n");
    o.arrays = R"(<DataArray type="Int16" Name="v" format="ascii">)" + values + "</DataArray>\n";
    write_file(p, vti(o));
    const Volume v = read_vti(p);
    EXPECT_EQ(v.dtype(), DType::i16);
    EXPECT_EQ(v.spacing(), (Vec3{0.5, 1, 2}));
    EXPECT_EQ(v.origin(), (Vec3{10.5, 20, 34}));  // Origin + M·(x0, y0, z0)
    expect_grid(v, kDims, -1, 7);
    expect_grid(read_volume(p), kDims, -1, 7);
}

TEST(VtiReader, AppendedRawAndBase64Uncompressed) {
    TempDir dir;
    const std::string other = bytes_of(std::vector<float>(60, 5.0f));
    const std::string data = bytes_of(grid_values<float>(kDims, 0.5));
    for (const bool wide : {false, true}) {
        const auto num = [&](std::uint64_t v) { return wide ? u64(v) : u32(static_cast<std::uint32_t>(v)); };
        VtiOptions o;
        o.file_attrs =
            std::string(R"(byte_order="LittleEndian" header_type=")") + (wide ? "UInt64" : "UInt32") + "\"";
        o.point_data_attrs = R"(Scalars="density")";
        const std::size_t second = num(0).size() + other.size();
        o.arrays = R"(<DataArray type="Float32" Name="other" format="appended" offset="0"/>)"
                   "\n"
                   R"(<DataArray type="Float32" Name="density" format="appended" offset=")" +
                   std::to_string(second) + "\"/>\n";
        o.appended = "<AppendedData encoding=\"raw\">\n   _" + num(other.size()) + other + num(data.size()) +
                     data + "\n</AppendedData>\n";
        const fs::path raw = dir / (wide ? "raw64.vti" : "raw32.vti");
        write_file(raw, vti(o));
        const Volume v = read_vti(raw);
        EXPECT_EQ(v.dtype(), DType::f32);
        expect_grid(v, kDims, 0.5);

        // base64: header and data as one stream, or as two padded streams; offsets count characters
        const std::string first = base64(num(other.size()) + other);
        for (const bool separate : {false, true}) {
            const std::string b =
                separate ? base64(num(data.size())) + base64(data) : base64(num(data.size()) + data);
            o.arrays = R"(<DataArray type="Float32" Name="other" format="appended" offset="0"/>)"
                       "\n"
                       R"(<DataArray type="Float32" Name="density" format="appended" offset=")" +
                       std::to_string(first.size()) + "\"/>\n";
            o.appended = "<AppendedData encoding=\"base64\">_" + first + b + "\n</AppendedData>\n";
            const fs::path p = dir / "b64.vti";
            write_file(p, vti(o));
            expect_grid(read_volume(p), kDims, 0.5);
        }
    }
}

TEST(VtiReader, ZlibBlocksInlineAndAppendedBothByteOrders) {
    TempDir dir;
    for (const bool big : {false, true}) {
        const std::string data = bytes_of(grid_values<std::uint16_t>(kDims, 100, 3), big);  // 120 bytes
        const std::string order = big ? "BigEndian" : "LittleEndian";
        for (const bool wide : {false, true}) {
            const auto [header, body] = zlib_blocks(data, 50, wide, big);  // 50 + 50 + a partial 20
            VtiOptions o;
            o.file_attrs = "byte_order=\"" + order + "\" header_type=\"" + (wide ? "UInt64" : "UInt32") +
                           "\" compressor=\"vtkZLibDataCompressor\"";
            o.arrays = "<DataArray type=\"UInt16\" Name=\"u\" format=\"binary\">\n  " + base64(header) +
                       base64(body) + "\n</DataArray>\n";
            const fs::path inl = dir / "inline.vti";
            write_file(inl, vti(o));
            const Volume a = read_vti(inl);
            EXPECT_EQ(a.dtype(), DType::u16);
            expect_grid(a, kDims, 100, 3);

            o.arrays = R"(<DataArray type="UInt16" Name="u" format="appended" offset="0"/>)";
            o.appended = "<AppendedData encoding=\"raw\">_" + header + body + "</AppendedData>";
            const fs::path app = dir / "appended.vti";
            write_file(app, vti(o));
            expect_grid(read_volume(app), kDims, 100, 3);
        }
        // inline uncompressed, big or little
        VtiOptions o;
        o.file_attrs = "byte_order=\"" + order + "\"";
        o.arrays = "<DataArray type=\"UInt16\" Name=\"u\" format=\"binary\">" + base64(u32(120, big) + data) +
                   "</DataArray>";
        write_file(dir / "plain.vti", vti(o));
        expect_grid(read_vti(dir / "plain.vti"), kDims, 100, 3);
    }
}

TEST(VtiReader, DirectionAndArrayChoice) {
    TempDir dir;
    const fs::path p = dir / "d.vti";
    VtiOptions o;
    o.image_attrs =
        R"(WholeExtent="0 4 0 3 0 2" Origin="1 1 1" Spacing="1 2 3" Direction="0 -1 0 1 0 0 0 0 1")";
    std::string values;
    for (auto x : grid_values<std::int32_t>(kDims)) values += std::to_string(x) + " ";
    o.arrays = R"(<DataArray type="Int32" Name="first" format="ascii">)" + values +
               "</DataArray>\n"
               R"(<DataArray type="Float64" Name="second" format="ascii">)" +
               values + "</DataArray>\n";
    write_file(p, vti(o));
    {
        WarningCatcher w;
        const Volume v = read_vti(p);
        EXPECT_TRUE(w.any("reading the first, 'first'"));
        EXPECT_EQ(v.dtype(), DType::i32);
        EXPECT_EQ(v.index_to_world({1, 0, 0}), (Vec3{1, 2, 1}));
        EXPECT_EQ(v.index_to_world({0, 1, 0}), (Vec3{-1, 1, 1}));
        EXPECT_EQ(v.index_to_world({0, 0, 1}), (Vec3{1, 1, 4}));
    }
    o.point_data_attrs = R"(Scalars="second")";
    write_file(p, vti(o));
    const Volume s = read_vti(p);
    EXPECT_EQ(s.dtype(), DType::f64);
    expect_grid(s, kDims);
}

TEST(VtiReaderErrors, CorruptTruncatedAndWrongSizes) {
    TempDir dir;
    const fs::path p = dir / "e.vti";
    const std::string data = bytes_of(grid_values<std::uint16_t>(kDims));
    const auto [header, body] = zlib_blocks(data, 50, false);
    VtiOptions o;
    o.file_attrs = R"(byte_order="LittleEndian" header_type="UInt32" compressor="vtkZLibDataCompressor")";
    o.arrays = R"(<DataArray type="UInt16" Name="u" format="appended" offset="0"/>)";
    const auto with_appended = [&](const std::string& bytes) {
        VtiOptions c = o;
        c.appended = "<AppendedData encoding=\"raw\">_" + bytes + "</AppendedData>";
        return vti(c);
    };
    // corrupted zlib stream: damage the middle of the first block
    std::string bad_body = body;
    for (std::size_t i = 4; i < 12; ++i) bad_body[i] = static_cast<char>(bad_body[i] ^ 0xff);
    write_file(p, with_appended(header + bad_body));
    expect_error([&] { read_vti(p); }, p, {"DataArray 'u'", "corrupt zlib data in block 0"});
    // a stream that ends early (a whole file cut inside the blocks)
    const std::string full = with_appended(header + body);
    write_file(p, full.substr(0, full.find('_', full.find("<AppendedData")) + 1 + header.size() + 30));
    expect_error([&] { read_vti(p); }, p, {"DataArray 'u'", "truncated"});
    // a compression header that does not add up to the extent
    auto [h2, b2] = zlib_blocks(data.substr(0, 100), 50, false);
    write_file(p, with_appended(h2 + b2));
    expect_error([&] { read_vti(p); }, p, {"does not describe the 120 bytes"});
    // a header claiming far more blocks than the file holds
    write_file(p, with_appended(u32(0x7fffffff) + u32(50) + u32(20)));
    expect_error([&] { read_vti(p); }, p, {"2147483647 blocks"});
    // uncompressed: wrong byte count, truncated data
    o.file_attrs = R"(byte_order="LittleEndian" header_type="UInt32")";
    write_file(p, with_appended(u32(118) + data));
    expect_error([&] { read_vti(p); }, p, {"118 bytes of data", "needs 120"});
    const std::string cut = with_appended(u32(120) + data);
    write_file(p, cut.substr(0, cut.find('_', cut.find("<AppendedData")) + 1 + 4 + 60));
    expect_error([&] { read_vti(p); }, p, {"truncated"});
    // inline base64 cut short, and with a bad character
    VtiOptions i = o;
    i.arrays = R"(<DataArray type="UInt16" Name="u" format="binary">)" +
               base64(u32(120) + data).substr(0, 80) + "</DataArray>";
    write_file(p, vti(i));
    expect_error([&] { read_vti(p); }, p, {"DataArray 'u'", "truncated"});
    i.arrays = R"(<DataArray type="UInt16" Name="u" format="binary">AAA*)" + base64(data) + "</DataArray>";
    write_file(p, vti(i));
    expect_error([&] { read_vti(p); }, p, {"invalid base64 character '*'"});
    i.arrays =
        R"(<DataArray type="UInt16" Name="u" format="ascii">1 2 3)" + std::string(60, ' ') + "</DataArray>";
    write_file(p, vti(i));
    expect_error([&] { read_vti(p); }, p, {"holds 3 values, expected 60"});
}

TEST(VtiReaderErrors, BadHeadersAndUnsupportedContent) {
    TempDir dir;
    const fs::path p = dir / "h.vti";
    std::string values;
    for (int n = 0; n < 60; ++n) values += "1 ";
    const std::string ascii = R"(<DataArray type="UInt8" Name="u" format="ascii">)" + values + "</DataArray>";
    const auto expect = [&](const VtiOptions& o, const std::vector<std::string>& words) {
        write_file(p, vti(o));
        expect_error([&] { read_vti(p); }, p, words);
    };
    VtiOptions o;
    o.arrays = ascii;
    write_file(p, vti(o));
    EXPECT_EQ(read_vti(p).value_range(), (std::array<double, 2>{1, 1}));

    VtiOptions c = o;
    c.file_attrs += R"( compressor="vtkLZ4DataCompressor")";
    expect(c, {"vtkLZ4DataCompressor", "unsupported"});
    c = o;
    c.file_attrs = R"(byte_order="MiddleEndian")";
    expect(c, {"byte_order"});
    c = o;
    c.file_attrs = R"(header_type="UInt16")";
    expect(c, {"header_type"});
    c = o;
    c.image_attrs = R"(WholeExtent="0 99999 0 99999 0 99999")";
    c.extent = "0 99999 0 99999 0 99999";
    expect(c, {"GiB limit"});
    c.image_attrs = R"(WholeExtent="0 4 0 3")";
    expect(c, {"WholeExtent"});
    c = o;
    c.image_attrs = R"(WholeExtent="0 4 3 0 0 2")";
    expect(c, {"WholeExtent", "max >= min"});
    c = o;
    c.image_attrs = R"(WholeExtent="0 4 0 3 0 2" Spacing="1 0 1")";
    expect(c, {"Spacing", "non-zero"});
    c = o;
    c.image_attrs = R"(WholeExtent="0 4 0 3 0 2" Direction="1 0 0 1 0 0 0 0 1")";
    expect(c, {"Direction", "singular"});
    c = o;
    c.extent = "0 2 0 3 0 2";
    expect(c, {"partial pieces"});
    c = o;
    c.arrays = R"(<DataArray type="Int64" Name="u" format="ascii">)" + values + "</DataArray>";
    expect(c, {"DataArray 'u'", "Int64", "unsupported"});
    c.arrays = R"(<DataArray type="UInt8" Name="u" NumberOfComponents="3" format="ascii">)" + values +
               "</DataArray>";
    expect(c, {"NumberOfComponents 3"});
    c.arrays = R"(<DataArray type="UInt8" Name="u" format="hex">00</DataArray>)";
    expect(c, {"format 'hex'"});
    c.arrays = R"(<DataArray type="UInt8" Name="u" format="appended" offset="0"/>)";
    expect(c, {"no <AppendedData>"});
    c.appended = "<AppendedData encoding=\"raw\">\n  x</AppendedData>";
    expect(c, {"'_' marker"});
    c.arrays = "";
    c.appended = "";
    expect(c, {"no PointData DataArray"});

    write_file(p, vti(o).substr(0, 200));
    expect_error([&] { read_vti(p); }, p, {"XML error"});
    std::string poly = vti(o);
    poly.replace(poly.find("ImageData"), 9, "PolyData");
    write_file(p, poly);
    expect_error([&] { read_vti(p); }, p, {"VTKFile type 'PolyData' is unsupported"});
    std::string two = vti(o);
    const std::size_t piece = two.find("<Piece");
    const std::size_t end = two.find("</Piece>") + 8;
    two.insert(end, two.substr(piece, end - piece));
    write_file(p, two);
    expect_error([&] { read_vti(p); }, p, {"2 pieces"});
}

TEST(VtiReaderErrors, MangledFilesNeverCrash) {
    TempDir dir;
    const fs::path p = dir / "m.vti";
    const std::string data = bytes_of(grid_values<std::uint16_t>(kDims));
    const auto [header, body] = zlib_blocks(data, 50, false);
    VtiOptions o;
    o.file_attrs = R"(byte_order="LittleEndian" header_type="UInt32" compressor="vtkZLibDataCompressor")";
    o.arrays = R"(<DataArray type="UInt16" Name="u" format="appended" offset="0"/>)";
    o.appended = "<AppendedData encoding=\"raw\">_" + header + body + "</AppendedData>";
    const std::string appended = vti(o);
    o.arrays = "<DataArray type=\"UInt16\" Name=\"u\" format=\"binary\">" + base64(header) + base64(body) +
               "</DataArray>";
    o.appended = "";
    const std::string inline_file = vti(o);
    WarningCatcher quiet;
    for (const std::string& good : {appended, inline_file}) {
        for (std::size_t n = 0; n < good.size(); n += 2) {
            write_file(p, good.substr(0, n));
            read_or_error(read_vti, p);
        }
        for (std::size_t i = 0; i < good.size(); ++i) {
            std::string bad = good;
            bad[i] = static_cast<char>(bad[i] ^ 0x21);
            write_file(p, bad);
            read_or_error(read_vti, p);
        }
    }
}

TEST(VtiShared, HydrogenZlibBase64) {
    FATHOM_REQUIRE_SHARED("sim_and_small_vtkdata/hydrogen.vti");
    const fs::path p = fathom::test::shared_data() / "sim_and_small_vtkdata/hydrogen.vti";
    WarningCatcher w;
    const Volume v = read_volume(p);
    EXPECT_TRUE(w.messages.empty());
    EXPECT_EQ(v.dims(), (Dims{64, 64, 64}));
    EXPECT_EQ(v.dtype(), DType::f32);
    EXPECT_EQ(v.spacing(), (Vec3{1, 1, 1}));
    EXPECT_EQ(v.origin(), (Vec3{0, 0, 0}));
    const Stats s = stats(v);
    EXPECT_EQ(s.min, 0.0);
    EXPECT_EQ(s.max, 1.0);
    EXPECT_EQ(v.value_range(), (std::array<double, 2>{0, 1}));
    EXPECT_EQ(v.value(31, 31, 21), 1.0);
    EXPECT_EQ(v.value(10, 20, 30), static_cast<double>(0.015506000258028507f));
}

// ================================================================ read_volume and fathom info

TEST(VtkFormatsDetect, ByContentAndByExtension) {
    TempDir dir;
    write_file(dir / "slc.dat", slc_file(kDims, 1));
    write_file(dir / "legacy.dat", vtk_header("BINARY", kDims, "unsigned_char") +
                                       bytes_of(grid_values<std::uint8_t>(kDims), true));
    VtiOptions o;
    std::string values;
    for (auto x : grid_values<std::uint8_t>(kDims)) values += std::to_string(x) + " ";
    o.arrays = R"(<DataArray type="UInt8" Name="u" format="ascii">)" + values + "</DataArray>";
    write_file(dir / "xml.dat", vti(o));
    for (const char* name : {"slc.dat", "legacy.dat", "xml.dat"}) expect_grid(read_volume(dir / name), kDims);
    // the extension picks the reader when the content is not recognised
    for (const char* name : {"x.slc", "x.vtk", "x.vti"}) {
        write_file(dir / name, "not a volume at all\n");
        expect_error([&] { read_volume(dir / name); }, dir / name, {});
    }
    expect_error([&] { read_volume(dir / "x.slc"); }, dir / "x.slc", {"not an SLC file"});
    expect_error([&] { read_volume(dir / "x.vtk"); }, dir / "x.vtk", {"not a legacy VTK file"});
    expect_error([&] { read_volume(dir / "x.vti"); }, dir / "x.vti", {"XML"});
}

TEST(VtkFormatsCli, InfoReadsEachFormat) {
    TempDir dir;
    write_file(dir / "v.slc", slc_file(kDims, 1));
    write_file(dir / "v.vtk", vtk_header("BINARY", kDims, "unsigned_char") +
                                  bytes_of(grid_values<std::uint8_t>(kDims), true));
    VtiOptions o;
    std::string values;
    for (auto x : grid_values<std::uint8_t>(kDims)) values += std::to_string(x) + " ";
    o.arrays = R"(<DataArray type="UInt8" Name="u" format="ascii">)" + values + "</DataArray>";
    write_file(dir / "v.vti", vti(o));
    for (const char* name : {"v.slc", "v.vtk", "v.vti"}) {
        const fs::path out = dir / "info.txt";
        const std::string cmd =
            fathom::test::cli() + " info " + (dir / name).string() + " > " + out.string() + " 2>&1";
        const int rc = std::system(cmd.c_str());
        ASSERT_TRUE(WIFEXITED(rc)) << name;
        EXPECT_EQ(WEXITSTATUS(rc), 0) << name;
        std::ifstream in(out);
        const std::string text{std::istreambuf_iterator<char>(in), std::istreambuf_iterator<char>()};
        EXPECT_NE(text.find("5 x 4 x 3"), std::string::npos) << name << ":\n" << text;
        EXPECT_NE(text.find("uint8"), std::string::npos) << name << ":\n" << text;
    }
}
