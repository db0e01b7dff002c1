// write_nrrd and `fathom convert`: every volume fathom holds (each type, 1 or
// 3 components, rotated placement, gzip or raw) reads back bit-identical,
// and so do the shared real files converted from their own formats.
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/io.h"

#include "test_util.h"

using namespace fathom;
using fathom::test::expect_error;
using fathom::test::TempDir;
namespace fs = std::filesystem;

namespace {

/// Same dims, type, components, placement (exact doubles) and bytes.
void expect_identical(const Volume& a, const Volume& b) {
    EXPECT_EQ(a.dims(), b.dims());
    EXPECT_EQ(a.dtype(), b.dtype());
    EXPECT_EQ(a.components(), b.components());
    EXPECT_EQ(a.origin().x, b.origin().x);
    EXPECT_EQ(a.origin().y, b.origin().y);
    EXPECT_EQ(a.origin().z, b.origin().z);
    for (int r = 0; r < 3; ++r)
        for (int c = 0; c < 3; ++c) EXPECT_EQ(a.axes().m[r][c], b.axes().m[r][c]) << r << "," << c;
    ASSERT_EQ(a.size_bytes(), b.size_bytes());
    EXPECT_EQ(std::memcmp(a.bytes(), b.bytes(), a.size_bytes()), 0);
}

/// A volume of the type with values that use the type's whole range
/// (negative, large, fractional), components interleaved.
Volume patterned(DType t, int components) {
    Volume v({5, 4, 3}, t, components);
    std::uint64_t h = 0x9e3779b97f4a7c15ull;
    const auto n = v.num_nodes() * components;
    for (std::int64_t i = 0; i < n; ++i) {
        h ^= h >> 12, h ^= h << 25, h ^= h >> 27;
        const auto bits = h * 0x2545F4914F6CDD1Dull;
        visit_dtype(t, [&]<class T>(T*) {
            T x;
            if constexpr (std::is_floating_point_v<T>)
                x = static_cast<T>(static_cast<double>(static_cast<std::int64_t>(bits)) * 1e-12);
            else
                std::memcpy(&x, &bits, sizeof x);
            v.data<T>()[i] = x;
        });
    }
    return v;
}

}  // namespace

TEST(NrrdWriter, EveryTypeAndComponentsRoundTripBitIdentical) {
    TempDir dir;
    for (DType t :
         {DType::u8, DType::i8, DType::u16, DType::i16, DType::u32, DType::i32, DType::f32, DType::f64})
        for (int comps : {1, 3})
            for (bool gzip : {true, false}) {
                SCOPED_TRACE(std::string(dtype_name(t)) + " c=" + std::to_string(comps) +
                             (gzip ? " gzip" : " raw"));
                Volume v = patterned(t, comps);
                // A rotated, anisotropic placement with digits that need all 17.
                const double a = 0.3;
                v.set_axes(Mat3::from_columns({0.1 * std::cos(a), 0.1 * std::sin(a), 0},
                                              {-0.7 * std::sin(a), 0.7 * std::cos(a), 0}, {0, 0, 1.0 / 3.0}));
                v.set_origin({-12.345678901234567, 1e-300, 98765.4321});
                const fs::path p = dir / ("v.nrrd");
                write_nrrd(p, v, gzip);
                expect_identical(v, read_nrrd(p));
                expect_identical(v, read_volume(p));
            }
}

TEST(NrrdWriter, GzipIsSmallerForSmoothDataAndRawIsExactSize) {
    TempDir dir;
    Volume v({64, 64, 64}, DType::u16);
    for (std::int64_t k = 0; k < 64; ++k)
        for (std::int64_t j = 0; j < 64; ++j)
            for (std::int64_t i = 0; i < 64; ++i) v.set_value(i, j, k, static_cast<double>(i + j + k));
    write_nrrd(dir / "g.nrrd", v, true);
    write_nrrd(dir / "r.nrrd", v, false);
    EXPECT_LT(fs::file_size(dir / "g.nrrd"), v.size_bytes() / 4);
    EXPECT_GT(fs::file_size(dir / "r.nrrd"), v.size_bytes());
    EXPECT_LT(fs::file_size(dir / "r.nrrd"), v.size_bytes() + 1024);
    expect_identical(v, read_volume(dir / "g.nrrd"));
}

TEST(NrrdWriter, HeaderSaysLpsAndTheType) {
    TempDir dir;
    write_nrrd(dir / "h.nrrd", patterned(DType::f32, 1), false);
    std::ifstream f(dir / "h.nrrd");
    std::stringstream ss;
    ss << f.rdbuf();
    const std::string text = ss.str();
    EXPECT_TRUE(text.starts_with("NRRD0004\n"));
    EXPECT_NE(text.find("space: left-posterior-superior\n"), std::string::npos);
    EXPECT_NE(text.find("type: float\n"), std::string::npos);
    EXPECT_NE(text.find("sizes: 5 4 3\n"), std::string::npos);
    EXPECT_NE(text.find("encoding: raw\n"), std::string::npos);
}

TEST(NrrdWriter, UnwritablePathIsAnErrorAndLeavesNothing) {
    TempDir dir;
    const fs::path p = dir / "missing" / "v.nrrd";
    expect_error([&] { write_nrrd(p, patterned(DType::u8, 1)); }, p, {});
    EXPECT_FALSE(fs::exists(p));
}

TEST(NrrdWriter, SharedFilesConvertBitIdentical) {
    FATHOM_REQUIRE_SHARED("sim_and_small_vtkdata");
    TempDir dir;
    const fs::path d = fathom::test::shared_data() / "sim_and_small_vtkdata";
    for (const char* name : {"hydrogen.vti", "ironProt.vtk", "neghip.slc", "headsq/quarter.nhdr"}) {
        SCOPED_TRACE(name);
        const Volume v = read_volume(d / name);
        write_nrrd(dir / "c.nrrd", v);
        expect_identical(v, read_volume(dir / "c.nrrd"));
    }
}

TEST(NrrdWriter, ConvertCommand) {
    FATHOM_REQUIRE_SHARED("sim_and_small_vtkdata/neghip.slc");
    TempDir dir;
    const fs::path in = fathom::test::shared_data() / "sim_and_small_vtkdata/neghip.slc";
    const fs::path out = dir / "n.nrrd";
    const std::string cmd =
        fathom::test::cli() + " convert '" + in.string() + "' '" + out.string() + "' >/dev/null";
    ASSERT_EQ(std::system(cmd.c_str()), 0);
    const Volume a = read_volume(in);
    expect_identical(a, read_volume(out));
    // Not .nrrd: a usage error (exit 2), nothing written.
    const fs::path bad = dir / "n.png";
    const std::string cmd2 =
        fathom::test::cli() + " convert '" + in.string() + "' '" + bad.string() + "' >/dev/null 2>&1";
    EXPECT_EQ(WEXITSTATUS(std::system(cmd2.c_str())), 2);
    EXPECT_FALSE(fs::exists(bad));
    // Unreadable input: exit 1, nothing written.
    const fs::path missing = dir / "none.nrrd";
    const std::string cmd3 = fathom::test::cli() + " convert '" + (dir / "x.vti").string() + "' '" +
                             missing.string() + "' 2>/dev/null";
    EXPECT_EQ(WEXITSTATUS(std::system(cmd3.c_str())), 1);
    EXPECT_FALSE(fs::exists(missing));
}
