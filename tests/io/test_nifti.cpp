// NIfTI reader (read_nifti, read_volume dispatch): the Colin27 MRI from the
// shared data, and NIfTI-1/-2 files written byte by byte here (headers built
// by hand, so that broken files can be made too).
#include <algorithm>
#include <array>
#include <bit>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <fstream>
#include <limits>
#include <optional>
#include <string>
#include <tuple>
#include <vector>

#include <gtest/gtest.h>
#include <zlib.h>

#include "fathom/error.h"
#include "fathom/io.h"

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

/// A gzip member of the bytes.
std::string gzip(const std::string& data) {
    z_stream zs{};
    EXPECT_EQ(deflateInit2(&zs, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY), Z_OK);
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

/// The whole decompressed content of a gzip file.
std::string gunzip_file(const fs::path& p) {
    gzFile f = gzopen(p.c_str(), "rb");
    EXPECT_NE(f, nullptr) << p;
    if (f == nullptr) return {};
    std::string out;
    std::vector<char> buf(std::size_t{1} << 20);
    int got = 0;
    while ((got = gzread(f, buf.data(), static_cast<unsigned>(buf.size()))) > 0)
        out.append(buf.data(), static_cast<std::size_t>(got));
    EXPECT_EQ(got, 0) << "gzip error in " << p;
    gzclose(f);
    return out;
}

bool swap_for(bool big_endian) {
    return big_endian != (std::endian::native == std::endian::big);
}

template <class T>
void put(std::string& buf, std::size_t offset, T value, bool big_endian) {
    std::array<char, sizeof(T)> b{};
    std::memcpy(b.data(), &value, sizeof(T));
    if (swap_for(big_endian)) std::reverse(b.begin(), b.end());
    std::memcpy(buf.data() + offset, b.data(), sizeof(T));
}

template <class T>
T get(const std::string& buf, std::size_t offset) {  // little-endian file, little-endian test machine
    T v;
    std::memcpy(&v, buf.data() + offset, sizeof(T));
    return v;
}

/// Samples as bytes in the requested byte order.
template <class T>
std::string bytes_of(const std::vector<T>& values, bool big_endian = false) {
    std::string out(values.size() * sizeof(T), '\0');
    for (std::size_t i = 0; i < values.size(); ++i) put(out, i * sizeof(T), values[i], big_endian);
    return out;
}

/// A NIfTI-1 (348-byte) or NIfTI-2 (540-byte) header, field by field.
struct Nifti {
    int version = 1;
    std::vector<std::int64_t> dim{4, 3, 2};  // dim[1..dim[0]]
    std::optional<std::int64_t> dim0;        // default: dim.size()
    int datatype = 2;                        // DT_UINT8
    int bitpix = 8;
    std::array<double, 3> pixdim{1, 1, 1};
    double qfac = 1;
    std::optional<double> vox_offset;  // default: right after the header (pair: 0)
    double slope = 0, inter = 0;
    int xyzt_units = 2;  // NIFTI_UNITS_MM
    int qform_code = 0, sform_code = 0;
    std::array<double, 6> quatern{};  // b, c, d, qoffset x, y, z
    std::array<std::array<double, 4>, 3> srow{};
    bool pair = false;
    bool big_endian = false;

    [[nodiscard]] std::size_t header_size() const { return version == 1 ? 348 : 540; }
    [[nodiscard]] double offset() const {
        return vox_offset ? *vox_offset : (pair ? 0.0 : static_cast<double>(header_size() + 4));
    }

    [[nodiscard]] std::string header() const {
        std::string b(header_size(), '\0');
        const bool be = big_endian;
        std::array<std::int64_t, 8> d{
            dim0 ? *dim0 : static_cast<std::int64_t>(dim.size()), 1, 1, 1, 1, 1, 1, 1};
        for (std::size_t a = 0; a < dim.size() && a < 7; ++a) d[a + 1] = dim[a];
        const std::array<double, 8> pd{qfac, pixdim[0], pixdim[1], pixdim[2], 1, 1, 1, 1};
        if (version == 1) {
            put<std::int32_t>(b, 0, 348, be);
            for (std::size_t a = 0; a < 8; ++a) put(b, 40 + 2 * a, static_cast<std::int16_t>(d[a]), be);
            put(b, 70, static_cast<std::int16_t>(datatype), be);
            put(b, 72, static_cast<std::int16_t>(bitpix), be);
            for (std::size_t a = 0; a < 8; ++a) put(b, 76 + 4 * a, static_cast<float>(pd[a]), be);
            put(b, 108, static_cast<float>(offset()), be);
            put(b, 112, static_cast<float>(slope), be);
            put(b, 116, static_cast<float>(inter), be);
            b[123] = static_cast<char>(xyzt_units);
            put(b, 252, static_cast<std::int16_t>(qform_code), be);
            put(b, 254, static_cast<std::int16_t>(sform_code), be);
            for (std::size_t a = 0; a < 6; ++a) put(b, 256 + 4 * a, static_cast<float>(quatern[a]), be);
            for (std::size_t r = 0; r < 3; ++r)
                for (std::size_t c = 0; c < 4; ++c)
                    put(b, 280 + 16 * r + 4 * c, static_cast<float>(srow[r][c]), be);
            b.replace(344, 4, pair ? std::string("ni1\0", 4) : std::string("n+1\0", 4));
        } else {
            put<std::int32_t>(b, 0, 540, be);
            b.replace(4, 8, pair ? std::string("ni2\0\r\n\032\n", 8) : std::string("n+2\0\r\n\032\n", 8));
            put(b, 12, static_cast<std::int16_t>(datatype), be);
            put(b, 14, static_cast<std::int16_t>(bitpix), be);
            for (std::size_t a = 0; a < 8; ++a) put<std::int64_t>(b, 16 + 8 * a, d[a], be);
            for (std::size_t a = 0; a < 8; ++a) put(b, 104 + 8 * a, pd[a], be);
            put(b, 168, static_cast<std::int64_t>(offset()), be);
            put(b, 176, slope, be);
            put(b, 184, inter, be);
            put<std::int32_t>(b, 344, qform_code, be);
            put<std::int32_t>(b, 348, sform_code, be);
            for (std::size_t a = 0; a < 6; ++a) put(b, 352 + 8 * a, quatern[a], be);
            for (std::size_t r = 0; r < 3; ++r)
                for (std::size_t c = 0; c < 4; ++c) put(b, 400 + 32 * r + 8 * c, srow[r][c], be);
            put<std::int32_t>(b, 500, xyzt_units, be);
        }
        return b;
    }
    /// A single .nii file: header, 4 zero extension bytes, data.
    [[nodiscard]] std::string single(const std::string& data) const {
        return header() + std::string(4, '\0') + data;
    }
};

std::vector<double> values_of(const Volume& v) {
    std::vector<double> out(static_cast<std::size_t>(v.num_nodes()));
    for (std::size_t i = 0; i < out.size(); ++i) out[i] = v.value_linear(static_cast<std::int64_t>(i));
    return out;
}

std::vector<double> ramp(std::size_t n, double scale = 1, double offset = 0) {
    std::vector<double> v(n);
    for (std::size_t i = 0; i < n; ++i) v[i] = static_cast<double>(i) * scale + offset;
    return v;
}

template <class T>
std::vector<T> cast_all(const std::vector<double>& v) {
    std::vector<T> out(v.size());
    for (std::size_t i = 0; i < v.size(); ++i) out[i] = static_cast<T>(v[i]);
    return out;
}

void expect_vec(const Vec3& a, const Vec3& b, double tol = 1e-9) {
    EXPECT_NEAR(a.x, b.x, tol);
    EXPECT_NEAR(a.y, b.y, tol);
    EXPECT_NEAR(a.z, b.z, tol);
}

void expect_axes(const Volume& v, const std::array<std::array<double, 3>, 3>& m, double tol = 1e-9) {
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c)
            EXPECT_NEAR(v.axes().m[r][c], m[r][c], tol) << "M[" << r << "][" << c << "]";
}

}  // namespace

// ================================================================ real data

TEST(NiftiReader, Colin27MatchesManifestAndSform) {
    FATHOM_REQUIRE_SHARED("mri_colin27_ch2better/ch2better.nii.gz");
    const fs::path file = test::shared_data() / "mri_colin27_ch2better/ch2better.nii.gz";
    const Volume v = read_volume(file);  // dispatched by its .nii.gz name
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{301, 370, 316}));
    EXPECT_EQ(v.dtype(), DType::u8);
    EXPECT_EQ(v.components(), 1);
    expect_vec(v.spacing(), {0.5, 0.5, 0.5});
    EXPECT_EQ(v.value_range(), (std::array<double, 2>{0, 130}));

    // the samples are the file's bytes after vox_offset, and the placement is
    // the sform (RAS+) with its x and y rows negated (LPS)
    const std::string raw = gunzip_file(file);
    ASSERT_GE(raw.size(), 348u);
    ASSERT_EQ(get<std::int32_t>(raw, 0), 348);
    ASSERT_GT(get<std::int16_t>(raw, 254), 0) << "sform_code";
    const auto vox_offset = static_cast<std::size_t>(get<float>(raw, 108));
    ASSERT_EQ(raw.size(), vox_offset + v.size_bytes());
    EXPECT_EQ(std::memcmp(raw.data() + vox_offset, v.bytes(), v.size_bytes()), 0);
    for (int r = 0; r < 3; ++r) {
        const double sign = r < 2 ? -1 : 1;
        for (int c = 0; c < 3; ++c)
            EXPECT_DOUBLE_EQ(v.axes().m[r][c], sign * get<float>(raw, 280 + 16 * r + 4 * c));
        EXPECT_DOUBLE_EQ(v.origin()[r], sign * get<float>(raw, 280 + 16 * r + 12));
    }
    // the file's sform: voxel (0,0,0) at RAS (-75, -107, -69.5), i towards +x (right)
    expect_vec(v.index_to_world({0, 0, 0}), {75, 107, -69.5});
    expect_vec(v.index_to_world({1, 0, 0}) - v.index_to_world({0, 0, 0}), {-0.5, 0, 0});
    expect_vec(v.index_to_world({0, 1, 0}) - v.index_to_world({0, 0, 0}), {0, -0.5, 0});
    expect_vec(v.index_to_world({0, 0, 1}) - v.index_to_world({0, 0, 0}), {0, 0, 0.5});
}

// ================================================================ types and scaling

template <class T>
void check_type_round_trip(int datatype, DType expected, bool big_endian, int version) {
    TempDir dir;
    const fs::path f = dir / "t.nii";
    Nifti h;
    h.version = version;
    h.datatype = datatype;
    h.bitpix = static_cast<int>(8 * sizeof(T));
    h.big_endian = big_endian;
    const double offset = std::is_signed_v<T> ? -12 : 0;
    const auto values = ramp(24, 1, offset);
    write_file(f, h.single(bytes_of(cast_all<T>(values), big_endian)));
    const Volume v = read_nifti(f);
    EXPECT_EQ(v.dtype(), expected) << "datatype " << datatype;
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{4, 3, 2}));
    EXPECT_EQ(values_of(v), values) << "datatype " << datatype << (big_endian ? " big-endian" : "");
}

TEST(NiftiReader, KeepsEachScalarTypeInBothByteOrders) {
    for (bool be : {false, true})
        for (int version : {1, 2}) {
            check_type_round_trip<std::uint8_t>(2, DType::u8, be, version);
            check_type_round_trip<std::int8_t>(256, DType::i8, be, version);
            check_type_round_trip<std::uint16_t>(512, DType::u16, be, version);
            check_type_round_trip<std::int16_t>(4, DType::i16, be, version);
            check_type_round_trip<std::uint32_t>(768, DType::u32, be, version);
            check_type_round_trip<std::int32_t>(8, DType::i32, be, version);
            check_type_round_trip<float>(16, DType::f32, be, version);
            check_type_round_trip<double>(64, DType::f64, be, version);
        }
}

TEST(NiftiReader, AppliesSlopeAndIntercept) {
    TempDir dir;
    const auto stored = ramp(24, 1, -5);
    const auto data = bytes_of(cast_all<std::int16_t>(stored));
    Nifti h;
    h.datatype = 4;
    h.bitpix = 16;

    h.slope = 2.5;
    h.inter = -10;
    write_file(dir / "s.nii", h.single(data));
    const Volume s = read_nifti(dir / "s.nii");
    EXPECT_EQ(s.dtype(), DType::f32);
    for (std::size_t i = 0; i < stored.size(); ++i)
        EXPECT_DOUBLE_EQ(s.value_linear(static_cast<std::int64_t>(i)), 2.5 * stored[i] - 10) << i;

    h.slope = 1;  // (1, 3): still a rescale
    h.inter = 3;
    write_file(dir / "i.nii", h.single(data));
    const Volume i = read_nifti(dir / "i.nii");
    EXPECT_EQ(i.dtype(), DType::f32);
    EXPECT_EQ(values_of(i), ramp(24, 1, -2));

    // identity scalings keep the stored type and values
    for (auto [slope, inter] : std::vector<std::pair<double, double>>{
             {0, 0}, {0, 7}, {std::numeric_limits<double>::quiet_NaN(), 0}, {1, 0}}) {
        h.slope = slope;
        h.inter = inter;
        write_file(dir / "u.nii", h.single(data));
        const Volume u = read_nifti(dir / "u.nii");
        EXPECT_EQ(u.dtype(), DType::i16) << "slope " << slope << " inter " << inter;
        EXPECT_EQ(values_of(u), stored) << "slope " << slope << " inter " << inter;
    }

    // float64 data stay float64 when scaled
    Nifti d;
    d.datatype = 64;
    d.bitpix = 64;
    d.slope = 0.5;
    d.inter = 1;
    write_file(dir / "d.nii", d.single(bytes_of(stored)));
    const Volume dv = read_nifti(dir / "d.nii");
    EXPECT_EQ(dv.dtype(), DType::f64);
    EXPECT_EQ(values_of(dv), ramp(24, 0.5, -1.5));

    // NIfTI-2 holds slope and intercept as doubles
    Nifti n2 = h;
    n2.version = 2;
    n2.slope = 0.1;
    n2.inter = 0;
    write_file(dir / "n2.nii", n2.single(data));
    const Volume v2 = read_nifti(dir / "n2.nii");
    EXPECT_EQ(v2.dtype(), DType::f32);
    EXPECT_FLOAT_EQ(static_cast<float>(v2.value_linear(23)), static_cast<float>(0.1 * 18));
}

TEST(NiftiReader, RefusesNonFiniteFloatsAndScaledOverflow) {
    TempDir dir;
    Nifti h;
    h.datatype = 16;
    h.bitpix = 32;
    auto values = cast_all<float>(ramp(24));
    values[7] = std::numeric_limits<float>::quiet_NaN();
    write_file(dir / "nan.nii", h.single(bytes_of(values)));
    expect_error([&] { read_nifti(dir / "nan.nii"); }, dir / "nan.nii", {"sample 7", "NaN"});

    values[7] = 1e30f;
    h.slope = 1e30;
    write_file(dir / "big.nii", h.single(bytes_of(values)));
    expect_error([&] { read_nifti(dir / "big.nii"); }, dir / "big.nii", {"scl_slope", "infinite"});
}

// ================================================================ placement

TEST(NiftiReader, SformWinsOverQformAndIsMappedToLps) {
    TempDir dir;
    Nifti h;
    h.sform_code = 2;
    h.srow = {{{0, 2, 0, 10}, {-3, 0, 0, 20}, {0, 0, 4, -30}}};  // a rotation about z, scaled
    h.qform_code = 1;
    h.quatern = {0, 0, 0, 100, 200, 300};
    h.pixdim = {7, 7, 7};
    write_file(dir / "s.nii", h.single(std::string(24, '\1')));
    const Volume v = read_nifti(dir / "s.nii");
    expect_axes(v, {{{0, -2, 0}, {3, 0, 0}, {0, 0, 4}}});
    expect_vec(v.origin(), {-10, -20, -30});
    expect_vec(v.spacing(), {3, 2, 4});
    expect_vec(v.index_to_world({1, 1, 1}), {-12, -17, -26});
}

TEST(NiftiReader, QformQuaternionWhenNoSform) {
    TempDir dir;
    Nifti h;
    h.qform_code = 1;
    h.sform_code = 0;
    h.srow = {{{9, 9, 9, 9}, {9, 9, 9, 9}, {9, 9, 9, 9}}};  // ignored: sform_code 0
    const double s = std::sqrt(0.5);
    h.quatern = {0, 0, s, 10, 20, 30};  // 90° about z: R = [[0,-1,0],[1,0,0],[0,0,1]]
    h.pixdim = {2, 3, 4};
    write_file(dir / "q.nii", h.single(std::string(24, '\1')));
    const Volume v = read_nifti(dir / "q.nii");
    // RAS: R·diag(2,3,4) = [[0,-3,0],[2,0,0],[0,0,4]]; LPS negates rows x and y
    expect_axes(v, {{{0, 3, 0}, {-2, 0, 0}, {0, 0, 4}}}, 1e-6);
    expect_vec(v.origin(), {-10, -20, 30});

    // qfac = -1 flips the third axis
    h.qfac = -1;
    write_file(dir / "qf.nii", h.single(std::string(24, '\1')));
    const Volume f = read_nifti(dir / "qf.nii");
    expect_axes(f, {{{0, 3, 0}, {-2, 0, 0}, {0, 0, -4}}}, 1e-6);
}

TEST(NiftiReader, PixdimWhenNoTransformAndUnits) {
    TempDir dir;
    Nifti h;
    h.pixdim = {0.5, 2, 3};
    h.srow = {{{9, 9, 9, 9}, {9, 9, 9, 9}, {9, 9, 9, 9}}};  // ignored: sform_code 0
    h.quatern = {0.5, 0.5, 0.5, 9, 9, 9};                   // ignored: qform_code 0
    write_file(dir / "p.nii", h.single(std::string(24, '\1')));
    const Volume v = read_nifti(dir / "p.nii");
    expect_axes(v, {{{-0.5, 0, 0}, {0, -2, 0}, {0, 0, 3}}});
    expect_vec(v.origin(), {0, 0, 0});
    expect_vec(v.spacing(), {0.5, 2, 3});

    // metres and microns become millimetres (matrix and offset)
    h.sform_code = 1;
    h.srow = {{{0.001, 0, 0, 0.1}, {0, 0.002, 0, 0.2}, {0, 0, 0.003, 0.3}}};
    h.xyzt_units = 1 | 8;  // metres, seconds
    write_file(dir / "m.nii", h.single(std::string(24, '\1')));
    const Volume m = read_nifti(dir / "m.nii");
    expect_axes(m, {{{-1, 0, 0}, {0, -2, 0}, {0, 0, 3}}}, 1e-6);
    expect_vec(m.origin(), {-100, -200, 300}, 1e-4);

    h.srow = {{{500, 0, 0, 1000}, {0, 500, 0, 0}, {0, 0, 250, 0}}};
    h.xyzt_units = 3;  // microns
    write_file(dir / "u.nii", h.single(std::string(24, '\1')));
    const Volume u = read_nifti(dir / "u.nii");
    expect_axes(u, {{{-0.5, 0, 0}, {0, -0.5, 0}, {0, 0, 0.25}}}, 1e-9);
    expect_vec(u.origin(), {-1, 0, 0});
}

TEST(NiftiReader, RefusesSingularOrNonFiniteSform) {
    TempDir dir;
    Nifti h;
    h.sform_code = 1;  // all-zero rows
    write_file(dir / "z.nii", h.single(std::string(24, '\1')));
    expect_error([&] { read_nifti(dir / "z.nii"); }, dir / "z.nii", {"sform", "singular"});
    h.srow = {{{1, 0, 0, 0}, {0, 1, 0, 0}, {0, 0, std::numeric_limits<double>::infinity(), 0}}};
    write_file(dir / "i.nii", h.single(std::string(24, '\1')));
    expect_error([&] { read_nifti(dir / "i.nii"); }, dir / "i.nii", {"sform", "non-finite"});
}

// ================================================================ files

TEST(NiftiReader, ReadsHdrImgPairsAndGzip) {
    TempDir dir;
    const auto values = ramp(24, 1, 100);
    const std::string data = bytes_of(cast_all<std::uint16_t>(values));
    Nifti h;
    h.datatype = 512;
    h.bitpix = 16;
    h.sform_code = 1;
    h.srow = {{{1, 0, 0, 5}, {0, 1, 0, 6}, {0, 0, 1, 7}}};

    write_file(dir / "single.nii", h.single(data));
    write_file(dir / "single.nii.gz", gzip(h.single(data)));
    Nifti p = h;
    p.pair = true;
    write_file(dir / "pair.hdr", p.header());
    write_file(dir / "pair.img", data);
    write_file(dir / "gzpair.hdr", p.header());
    write_file(dir / "gzpair.img.gz", gzip(data));
    Nifti p2 = p;
    p2.version = 2;
    write_file(dir / "pair2.hdr", p2.header());
    write_file(dir / "pair2.img", data);
    Nifti s2 = h;
    s2.version = 2;
    write_file(dir / "two.nii.gz", gzip(s2.single(data)));

    for (const char* name :
         {"single.nii", "single.nii.gz", "pair.hdr", "pair.img", "gzpair.hdr", "pair2.hdr", "two.nii.gz"}) {
        SCOPED_TRACE(name);
        const bool by_content = std::string(name) != "pair.img";  // read_volume needs the header's name
        std::vector<Volume> read{read_nifti(dir / name)};
        if (by_content) read.push_back(read_volume(dir / name));
        for (const Volume& v : read) {
            EXPECT_EQ(v.dtype(), DType::u16);
            EXPECT_EQ(values_of(v), values);
            expect_vec(v.origin(), {-5, -6, 7});
            expect_axes(v, {{{-1, 0, 0}, {0, -1, 0}, {0, 0, 1}}});
        }
    }

    // Analyze 7.5 (no NIfTI magic): a pair placed by its voxel sizes, no scaling
    Nifti a = p;
    a.pixdim = {2, 3, 4};
    a.slope = 5;
    std::string analyze = a.header();
    analyze.replace(344, 4, std::string(4, '\0'));
    write_file(dir / "analyze.hdr", analyze);
    write_file(dir / "analyze.img", data);
    const Volume av = read_volume(dir / "analyze.hdr");
    EXPECT_EQ(av.dtype(), DType::u16);
    EXPECT_EQ(values_of(av), values);
    expect_axes(av, {{{-2, 0, 0}, {0, -3, 0}, {0, 0, 4}}});
    expect_vec(av.origin(), {0, 0, 0});

    // found by content whatever the name: gzip without .gz, no extension
    write_file(dir / "gz.nii", gzip(h.single(data)));
    write_file(dir / "scan.dat", h.single(data));
    write_file(dir / "noext", s2.single(data));
    write_file(dir / "gznoext", gzip(s2.single(data)));
    for (const char* name : {"gz.nii", "scan.dat", "noext", "gznoext"}) {
        SCOPED_TRACE(name);
        std::vector<Volume> read{read_nifti(dir / name)};
        if (std::string(name) != "gznoext") read.push_back(read_volume(dir / name));  // sniffs raw bytes only
        for (const Volume& v : read) {
            EXPECT_EQ(values_of(v), values);
            expect_vec(v.origin(), {-5, -6, 7});
        }
    }

    // a 4D or 5D file whose extra axes have one sample is one volume
    Nifti d4 = h;
    d4.dim = {4, 3, 2, 1, 1};
    write_file(dir / "d5.nii", d4.single(data));
    EXPECT_EQ(values_of(read_nifti(dir / "d5.nii")), values);

    // extensions between the header and vox_offset are skipped
    Nifti e = h;
    e.vox_offset = 352 + 32;
    std::string ext = std::string("\1\0\0\0", 4) + std::string(32, '\0');
    put<std::int32_t>(ext, 4, 32, false);  // esize
    put<std::int32_t>(ext, 8, 6, false);   // ecode: comment
    write_file(dir / "ext.nii", e.header() + ext + data);
    EXPECT_EQ(values_of(read_nifti(dir / "ext.nii")), values);
}

// ================================================================ errors

TEST(NiftiReader, TruncatedAndCorruptFiles) {
    TempDir dir;
    Nifti h;
    h.dim = {16, 16, 16};
    std::string data(4096, '\0');
    for (std::size_t i = 0; i < data.size(); ++i) data[i] = static_cast<char>(i * 7 % 251);
    const std::string whole = h.single(data);

    write_file(dir / "short.nii", whole.substr(0, whole.size() - 1000));
    expect_error([&] { read_nifti(dir / "short.nii"); }, dir / "short.nii",
                 {"truncated", "expected 4096 bytes", "from byte 352", "found 3096"});

    write_file(dir / "hdr.nii", whole.substr(0, 200));
    expect_error([&] { read_nifti(dir / "hdr.nii"); }, dir / "hdr.nii", {"truncated header", "200", "348"});
    write_file(dir / "tiny.nii", "ab");
    expect_error([&] { read_nifti(dir / "tiny.nii"); }, dir / "tiny.nii", {"truncated header"});

    Nifti n2 = h;
    n2.version = 2;
    write_file(dir / "hdr2.nii", n2.single(data).substr(0, 400));
    expect_error([&] { read_nifti(dir / "hdr2.nii"); }, dir / "hdr2.nii", {"truncated header", "400", "540"});

    const std::string gz = gzip(whole);
    write_file(dir / "short.nii.gz", gz.substr(0, gz.size() / 2));
    expect_error([&] { read_nifti(dir / "short.nii.gz"); }, dir / "short.nii.gz", {"ends early"});
    write_file(dir / "cut.nii.gz", gz.substr(0, 30));
    expect_error([&] { read_nifti(dir / "cut.nii.gz"); }, dir / "cut.nii.gz",
                 {"truncated header", "decompresses"});

    std::string bad_start = gz;  // a reserved deflate block type right after the gzip header
    std::fill(bad_start.begin() + 10, bad_start.begin() + 40, '\xff');
    write_file(dir / "bad.nii.gz", bad_start);
    expect_error([&] { read_nifti(dir / "bad.nii.gz"); }, dir / "bad.nii.gz",
                 {"corrupt gzip", "(the header): invalid block type"});

    std::string bad_crc = gz;  // the trailer's CRC-32 no longer matches the data
    bad_crc[bad_crc.size() - 6] = static_cast<char>(bad_crc[bad_crc.size() - 6] ^ 0x5a);
    write_file(dir / "crc.nii.gz", bad_crc);
    expect_error([&] { read_nifti(dir / "crc.nii.gz"); }, dir / "crc.nii.gz",
                 {"corrupt", "incorrect data check"});

    Nifti inside = h;
    inside.vox_offset = 100;
    write_file(dir / "inside.nii", inside.single(data));
    expect_error([&] { read_nifti(dir / "inside.nii"); }, dir / "inside.nii",
                 {"vox_offset is 100", "inside the 348-byte header"});
    inside.vox_offset = -4;
    write_file(dir / "neg.nii", inside.single(data));
    expect_error([&] { read_nifti(dir / "neg.nii"); }, dir / "neg.nii", {"vox_offset", "not a byte offset"});
    inside.vox_offset = 352 + 1e6;  // past the end: truncated
    write_file(dir / "far.nii", inside.single(data));
    expect_error([&] { read_nifti(dir / "far.nii"); }, dir / "far.nii",
                 {"truncated", "from byte 1000352", "found 0"});

    Nifti p = h;
    p.pair = true;
    write_file(dir / "lone.hdr", p.header());
    expect_error([&] { read_nifti(dir / "lone.hdr"); }, dir / "lone.hdr",
                 {"image file " + (dir / "lone.img").string() + " does not exist"});
    write_file(dir / "short.hdr", p.header());
    write_file(dir / "short.img", data.substr(0, 100));
    expect_error([&] { read_nifti(dir / "short.hdr"); }, dir / "short.hdr",
                 {"truncated", "short.img", "found 100"});

    write_file(dir / "orphan.img", data);
    expect_error([&] { read_nifti(dir / "orphan.img"); }, dir / "orphan.img", {"no .hdr header"});
    expect_error([&] { read_nifti(dir / "missing.nii"); }, dir / "missing.nii", {"does not exist"});
    write_file(dir / "text.nii", std::string(600, 'x'));
    expect_error([&] { read_nifti(dir / "text.nii"); }, dir / "text.nii", {"not a NIfTI file", "sizeof_hdr"});
}

TEST(NiftiReader, RefusesAbsurdDimensionsBeforeAllocating) {
    TempDir dir;
    Nifti h;
    h.dim = {30000, 30000, 30000};
    write_file(dir / "huge.nii", h.single(std::string(24, '\0')));
    expect_error([&] { read_nifti(dir / "huge.nii"); }, dir / "huge.nii", {"GiB", "limit"});
    write_file(dir / "huge.nii.gz", gzip(h.single(std::string(24, '\0'))));
    expect_error([&] { read_nifti(dir / "huge.nii.gz"); }, dir / "huge.nii.gz", {"GiB", "limit"});

    Nifti n2;
    n2.version = 2;
    n2.dim = {std::int64_t{1} << 40, std::int64_t{1} << 40, std::int64_t{1} << 40};
    write_file(dir / "huge2.nii", n2.single(std::string(24, '\0')));
    expect_error([&] { read_nifti(dir / "huge2.nii"); }, dir / "huge2.nii", {"GiB", "limit"});

    Nifti neg;
    neg.dim = {4, -3, 2};
    write_file(dir / "neg.nii", neg.single(std::string(24, '\0')));
    expect_error([&] { read_nifti(dir / "neg.nii"); }, dir / "neg.nii", {"dim[2] is -3"});

    Nifti d0;
    d0.dim0 = 9;
    write_file(dir / "d0.nii", d0.single(std::string(24, '\0')));
    expect_error([&] { read_nifti(dir / "d0.nii"); }, dir / "d0.nii", {"dim[0] is 9"});
}

TEST(NiftiReader, RefusesUnsupportedDatatypes) {
    TempDir dir;
    for (auto [code, bits, name] : std::vector<std::tuple<int, int, std::string>>{{32, 64, "COMPLEX64"},
                                                                                  {128, 24, "RGB24"},
                                                                                  {1024, 64, "INT64"},
                                                                                  {1280, 64, "UINT64"},
                                                                                  {1, 1, "BINARY"},
                                                                                  {2304, 32, "RGBA32"}}) {
        Nifti h;
        h.datatype = code;
        h.bitpix = bits;
        const fs::path f = dir / (name + ".nii");
        write_file(f, h.single(std::string(24 * 8, '\0')));
        expect_error([&] { read_nifti(f); }, f, {"unsupported NIfTI datatype " + name, std::to_string(code)});
    }
    Nifti h;
    h.datatype = 999;
    write_file(dir / "999.nii", h.single(std::string(24, '\0')));
    expect_error([&] { read_nifti(dir / "999.nii"); }, dir / "999.nii", {"unknown NIfTI datatype", "999"});
}

TEST(NiftiReader, RefusesSeveralVolumesAndFlatImages) {
    TempDir dir;
    Nifti h;
    h.dim = {4, 3, 2, 5};
    write_file(dir / "t.nii", h.single(std::string(120, '\0')));
    expect_error([&] { read_nifti(dir / "t.nii"); }, dir / "t.nii",
                 {"4D NIfTI with 5 volumes", "only one 3D volume is supported"});
    h.version = 2;
    write_file(dir / "t2.nii", h.single(std::string(120, '\0')));
    expect_error([&] { read_nifti(dir / "t2.nii"); }, dir / "t2.nii", {"4D NIfTI with 5 volumes"});

    Nifti vec;
    vec.dim = {4, 3, 2, 1, 3};  // a vector per voxel
    write_file(dir / "v.nii", vec.single(std::string(72, '\0')));
    expect_error([&] { read_nifti(dir / "v.nii"); }, dir / "v.nii", {"5D NIfTI", "4 x 3 x 2 x 1 x 3"});

    Nifti flat;
    flat.dim = {4, 3};
    write_file(dir / "2d.nii", flat.single(std::string(12, '\0')));
    expect_error([&] { read_nifti(dir / "2d.nii"); }, dir / "2d.nii", {"4 x 3 x 1", "at least 2 samples"});
    flat.dim = {4, 3, 1};
    write_file(dir / "slice.nii", flat.single(std::string(12, '\0')));
    expect_error([&] { read_nifti(dir / "slice.nii"); }, dir / "slice.nii",
                 {"4 x 3 x 1", "at least 2 samples"});
}

TEST(NiftiReader, PrintsNothingOnStderr) {
    TempDir dir;
    Nifti h;
    write_file(dir / "ok.nii", h.single(std::string(24, '\1')));
    write_file(dir / "hdr.nii", h.single(std::string(24, '\1')).substr(0, 100));
    write_file(dir / "text.nii", std::string(600, 'x'));
    Nifti p = h;
    p.pair = true;
    write_file(dir / "lone.hdr", p.header());
    h.datatype = 999;
    write_file(dir / "dt.nii", h.single(std::string(24, '\1')));
    testing::internal::CaptureStderr();
    EXPECT_NO_THROW(read_nifti(dir / "ok.nii"));
    for (const char* name : {"hdr.nii", "text.nii", "lone.hdr", "dt.nii"})
        EXPECT_THROW(read_nifti(dir / name), Error);
    EXPECT_EQ(testing::internal::GetCapturedStderr(), "");
}
