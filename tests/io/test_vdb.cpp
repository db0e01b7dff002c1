// OpenVDB reader: list_vdb_grids, read_vdb and read_volume's dispatch, on the
// shared Disney cloud and dragon files and on small grids written here with
// OpenVDB itself (placement, types, thin and empty grids, error paths).
#include <openvdb/io/File.h>
#include <openvdb/io/Stream.h>
#include <openvdb/openvdb.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <numbers>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"

#include "test_util.h"

using namespace fathom;
using fathom::test::expect_error;
using fathom::test::TempDir;
namespace fs = std::filesystem;

namespace {

// The reader runs OpenVDB in a forked child (src/io/vdb_reader.cpp), and fork
// copies only the calling thread. TBB worker threads started in this process
// (OpenVDB's tree statistics, when these tests write and check their
// fixtures) would leave the child's TBB waiting on them forever: about one
// run in a few hundred hung in `spawn` so. fathom's own processes never run
// TBB before they fork; this one keeps TBB on its calling thread.
const tbb::global_control kOneThread(tbb::global_control::max_allowed_parallelism, 1);

const char* const kCloud = "vdb_wdas_cloud/wdas_cloud_sixteenth.vdb";
const char* const kDragon = "vdb_wdas_cloud/dragon_fog_vpt.vdb";

fs::path shared(const char* rel) {
    return fathom::test::shared_data() / rel;
}

/// The grid as OpenVDB reads it (the reference the reader is compared with).
openvdb::FloatGrid::Ptr reference_grid(const fs::path& path, const std::string& name = "density") {
    openvdb::initialize();
    openvdb::io::File file(path.string());
    file.open(false);
    auto grid = openvdb::gridPtrCast<openvdb::FloatGrid>(file.readGrid(name));
    file.close();
    return grid;
}

/// Active voxels counted by iterating the grid (voxels and tiles).
std::uint64_t count_active(const openvdb::FloatGrid& grid) {
    std::uint64_t n = 0;
    for (auto it = grid.cbeginValueOn(); it; ++it) n += it.getVoxelCount();
    return n;
}

void write_vdb(const fs::path& path, const openvdb::GridPtrVec& grids, bool stats = true) {
    openvdb::initialize();
    openvdb::io::File file(path.string());
    file.setGridStatsMetadataEnabled(stats);
    file.write(grids);
    file.close();
}

void write_bytes(const fs::path& p, const std::string& bytes) {
    std::ofstream f(p, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(f.good()) << p;
}

std::string read_whole(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

/// Every node of v equals the grid's accessor value at bbox_min + (i, j, k) and sits where the
/// grid's transform puts that index.
template <class GridT>
void expect_matches_grid(const Volume& v, const GridT& grid, const openvdb::Coord& lo) {
    auto acc = grid.getConstAccessor();
    std::int64_t mismatches = 0;
    for (std::int64_t k = 0; k < v.dims()[2]; ++k)
        for (std::int64_t j = 0; j < v.dims()[1]; ++j)
            for (std::int64_t i = 0; i < v.dims()[0]; ++i) {
                const openvdb::Coord ijk(lo.x() + static_cast<int>(i), lo.y() + static_cast<int>(j),
                                         lo.z() + static_cast<int>(k));
                if (static_cast<float>(v.value(i, j, k)) != static_cast<float>(acc.getValue(ijk)))
                    ++mismatches;
            }
    EXPECT_EQ(mismatches, 0);
    for (const auto& ijk :
         {openvdb::Vec3d(0, 0, 0), openvdb::Vec3d(1, 0, 0), openvdb::Vec3d(0, 1, 0), openvdb::Vec3d(0, 0, 1),
          openvdb::Vec3d(static_cast<double>(v.dims()[0] - 1), static_cast<double>(v.dims()[1] - 1),
                         static_cast<double>(v.dims()[2] - 1))}) {
        const openvdb::Vec3d w = grid.transform().indexToWorld(lo.asVec3d() + ijk);
        const Vec3 p = v.index_to_world(Vec3(ijk[0], ijk[1], ijk[2]));
        EXPECT_NEAR(p.x, w[0], 1e-9 * (1 + std::abs(w[0])));
        EXPECT_NEAR(p.y, w[1], 1e-9 * (1 + std::abs(w[1])));
        EXPECT_NEAR(p.z, w[2], 1e-9 * (1 + std::abs(w[2])));
    }
}

/// Collects warnings while alive.
class WarningCapture {
public:
    WarningCapture() : previous_(set_warning_sink([this](const std::string& m) { messages.push_back(m); })) {}
    ~WarningCapture() { set_warning_sink(previous_); }
    WarningCapture(const WarningCapture&) = delete;
    WarningCapture& operator=(const WarningCapture&) = delete;
    std::vector<std::string> messages;

private:
    WarningSink previous_;
};

}  // namespace

// ================================================================ shared files

TEST(VdbReader, ListsTheCloudGrid) {
    FATHOM_REQUIRE_SHARED(kCloud);
    const auto grids = list_vdb_grids(shared(kCloud));
    ASSERT_EQ(grids.size(), 1u);
    EXPECT_EQ(grids[0].name, "density");
    EXPECT_EQ(grids[0].type, "float");
    // The count and box come from the file's statistics metadata: compare with the grid itself.
    const auto grid = reference_grid(shared(kCloud));
    ASSERT_TRUE(grid);
    EXPECT_GT(grids[0].active_voxels, 0u);
    EXPECT_EQ(grids[0].active_voxels, count_active(*grid));
    EXPECT_EQ(grids[0].active_voxels, grid->activeVoxelCount());
    const auto box = grid->evalActiveVoxelBoundingBox();
    for (int a = 0; a < 3; ++a) {
        EXPECT_EQ(grids[0].bbox_min[a], box.min()[a]);
        EXPECT_EQ(grids[0].bbox_max[a], box.max()[a]);
    }
    // MANIFEST: about 126 x 86 x 154 voxels.
    EXPECT_EQ(grids[0].bbox_max[0] - grids[0].bbox_min[0] + 1, 126);
    EXPECT_EQ(grids[0].bbox_max[1] - grids[0].bbox_min[1] + 1, 86);
    EXPECT_EQ(grids[0].bbox_max[2] - grids[0].bbox_min[2] + 1, 154);
}

TEST(VdbReader, ReadsTheCloudDensely) {
    FATHOM_REQUIRE_SHARED(kCloud);
    const Volume v = read_vdb(shared(kCloud));
    const auto grid = reference_grid(shared(kCloud));
    const auto box = grid->evalActiveVoxelBoundingBox();
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{126, 86, 154}));
    EXPECT_EQ(v.dtype(), DType::f32);
    EXPECT_EQ(v.components(), 1);
    EXPECT_TRUE(v.axes().is_diagonal());
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(v.spacing()[a], 10.0 / 3.0, 1e-4);  // voxel 3.333
    // The origin is the world position of the active box's minimum corner.
    const openvdb::Vec3d o = grid->transform().indexToWorld(box.min());
    EXPECT_NEAR(v.origin().x, o[0], 1e-9);
    EXPECT_NEAR(v.origin().y, o[1], 1e-9);
    EXPECT_NEAR(v.origin().z, o[2], 1e-9);
    EXPECT_NEAR(v.origin().x, -66 * 10.0 / 3.0, 1e-3);
    const auto range = v.value_range();
    EXPECT_GE(range[0], 0.0);
    EXPECT_LE(range[1], 1.0);
    EXPECT_GT(range[1], 0.5);
    // Every voxel, active or not, equals the grid's value at its index.
    expect_matches_grid(v, *grid, box.min());
    // The nonzero voxels: at most the active ones (inactive voxels read the background, 0).
    std::int64_t nonzero = 0;
    for (std::int64_t n = 0; n < v.num_nodes(); ++n) nonzero += v.value_linear(n) != 0.0;
    EXPECT_GT(nonzero, 100000);
    EXPECT_LE(static_cast<std::uint64_t>(nonzero), count_active(*grid));
    // A specific voxel: the cloud's value at index (0, 30, 0) is node (66, 51, 90).
    EXPECT_EQ(static_cast<float>(v.value(66, 51, 90)), grid->tree().getValue(openvdb::Coord(0, 30, 0)));
}

TEST(VdbReader, ReadsTheDragon) {
    FATHOM_REQUIRE_SHARED(kDragon);
    const auto grids = list_vdb_grids(shared(kDragon));
    ASSERT_EQ(grids.size(), 1u);
    EXPECT_EQ(grids[0].name, "density");
    EXPECT_EQ(grids[0].type, "float");
    const auto grid = reference_grid(shared(kDragon));
    EXPECT_EQ(grids[0].active_voxels, count_active(*grid));
    EXPECT_EQ(grids[0].bbox_min, (std::array<std::int64_t, 3>{16, 1, 35}));
    EXPECT_EQ(grids[0].bbox_max, (std::array<std::int64_t, 3>{85, 49, 65}));

    const Volume v = read_vdb(shared(kDragon));
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{70, 49, 31}));
    for (int a = 0; a < 3; ++a) EXPECT_NEAR(v.spacing()[a], 0.1, 1e-7);
    EXPECT_NEAR(v.origin().x, 1.6, 1e-6);
    EXPECT_NEAR(v.origin().y, 0.1, 1e-6);
    EXPECT_NEAR(v.origin().z, 3.5, 1e-6);
    const auto range = v.value_range();
    EXPECT_GE(range[0], 0.0);
    EXPECT_DOUBLE_EQ(range[1], 1.0);
    expect_matches_grid(v, *grid, openvdb::Coord(16, 1, 35));
}

TEST(VdbReader, ReadVolumeDispatchesWithTheGridOption) {
    FATHOM_REQUIRE_SHARED(kDragon);
    const Volume v = read_volume(shared(kDragon));
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{70, 49, 31}));
    ReadOptions options;
    options.grid = "density";
    EXPECT_EQ(read_volume(shared(kDragon), options).dims(), v.dims());
    options.grid = "x";
    expect_error([&] { read_volume(shared(kDragon), options); }, shared(kDragon),
                 {"no grid named 'x'", "'density' (float)"});

    // By content, whatever the name; by extension, whatever the content.
    TempDir dir;
    fs::copy_file(shared(kDragon), dir / "dragon.bin");
    EXPECT_EQ(read_volume(dir / "dragon.bin").dims(), v.dims());
    write_bytes(dir / "fake.vdb", "this is not a VDB file, just text with a .vdb name\n");
    expect_error([&] { read_volume(dir / "fake.vdb"); }, dir / "fake.vdb", {"not an OpenVDB file"});
}

// ================================================================ written here

TEST(VdbReader, RotatedTranslatedDoubleGrid) {
    TempDir dir;
    auto grid = openvdb::DoubleGrid::create(-1.0);
    grid->setName("density");
    // index → world: scale (0.5, 0.25, 2), rotate 30° about z, translate (10, -20, 30).
    openvdb::math::Mat4d m = openvdb::math::Mat4d::identity();
    m.preScale(openvdb::Vec3d(0.5, 0.25, 2.0));
    m.postRotate(openvdb::math::Z_AXIS, std::numbers::pi / 6);
    m.postTranslate(openvdb::Vec3d(10, -20, 30));
    grid->setTransform(openvdb::math::Transform::createLinearTransform(m));
    auto acc = grid->getAccessor();
    for (int k = 5; k <= 7; ++k)
        for (int j = -1; j <= 2; ++j)
            for (int i = 2; i <= 4; ++i)
                acc.setValue(openvdb::Coord(i, j, k), i + 10.0 * j + 100.0 * k + 0.125);
    acc.setValueOff(openvdb::Coord(3, 0, 6), 7.5);  // inactive, not the background
    write_vdb(dir / "r.vdb", {grid});

    const auto grids = list_vdb_grids(dir / "r.vdb");
    ASSERT_EQ(grids.size(), 1u);
    EXPECT_EQ(grids[0].type, "double");
    EXPECT_EQ(grids[0].active_voxels, 3u * 4u * 3u - 1u);
    EXPECT_EQ(grids[0].bbox_min, (std::array<std::int64_t, 3>{2, -1, 5}));
    EXPECT_EQ(grids[0].bbox_max, (std::array<std::int64_t, 3>{4, 2, 7}));

    const Volume v = read_vdb(dir / "r.vdb");
    EXPECT_EQ(v.dtype(), DType::f32);
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{3, 4, 3}));
    EXPECT_FALSE(v.axes().is_diagonal());
    EXPECT_NEAR(v.spacing().x, 0.5, 1e-12);
    EXPECT_NEAR(v.spacing().y, 0.25, 1e-12);
    EXPECT_NEAR(v.spacing().z, 2.0, 1e-12);
    EXPECT_FLOAT_EQ(static_cast<float>(v.value(0, 0, 0)), 2 - 10 + 500 + 0.125f);
    EXPECT_FLOAT_EQ(static_cast<float>(v.value(2, 3, 2)), 4 + 20 + 700 + 0.125f);
    EXPECT_FLOAT_EQ(static_cast<float>(v.value(1, 1, 1)), 7.5f);  // the stored inactive value
    expect_matches_grid(v, *grid, openvdb::Coord(2, -1, 5));
    // The first axis step is (0.5 cos 30°, 0.5 sin 30°, 0).
    EXPECT_NEAR(v.axes().column(0).x, 0.5 * std::cos(std::numbers::pi / 6), 1e-12);
    EXPECT_NEAR(v.axes().column(0).y, 0.5 * std::sin(std::numbers::pi / 6), 1e-12);
}

TEST(VdbReader, SeveralGridsAndTypes) {
    TempDir dir;
    auto density = openvdb::FloatGrid::create(0.0f);
    density->setName("density");
    density->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
    density->tree().setValue(openvdb::Coord(3, 4, 5), 2.0f);
    auto temperature = openvdb::FloatGrid::create(0.5f);
    temperature->setName("temperature");
    temperature->setTransform(openvdb::math::Transform::createLinearTransform(0.25));
    // An active tile (a whole 8^3 leaf's worth) and a voxel.
    temperature->tree().fill(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(7)), 3.0f, true);
    temperature->tree().setValue(openvdb::Coord(10, 1, 1), 4.0f);
    auto vel = openvdb::Vec3SGrid::create();
    vel->setName("vel");
    vel->tree().setValue(openvdb::Coord(1, 1, 1), openvdb::Vec3s(1, 2, 3));
    auto flags = openvdb::Int32Grid::create();
    flags->setName("flags");
    flags->tree().setValue(openvdb::Coord(1, 1, 1), 7);
    write_vdb(dir / "m.vdb", {density, temperature, vel, flags});

    for (bool stats : {true, false}) {
        SCOPED_TRACE(stats ? "with statistics metadata" : "without statistics metadata");
        write_vdb(dir / "m.vdb", {density, temperature, vel, flags}, stats);
        const auto grids = list_vdb_grids(dir / "m.vdb");
        ASSERT_EQ(grids.size(), 4u);
        EXPECT_EQ(grids[0].name, "density");
        EXPECT_EQ(grids[0].type, "float");
        EXPECT_EQ(grids[0].active_voxels, 2u);
        EXPECT_EQ(grids[0].bbox_max, (std::array<std::int64_t, 3>{3, 4, 5}));
        EXPECT_EQ(grids[1].name, "temperature");
        EXPECT_EQ(grids[1].active_voxels, 513u);
        EXPECT_EQ(grids[1].bbox_min, (std::array<std::int64_t, 3>{0, 0, 0}));
        EXPECT_EQ(grids[1].bbox_max, (std::array<std::int64_t, 3>{10, 7, 7}));
        EXPECT_EQ(grids[2].name, "vel");
        EXPECT_EQ(grids[2].type, "vec3s");
        EXPECT_EQ(grids[3].type, "int32");
    }

    const Volume t = read_vdb(dir / "m.vdb", "temperature");
    EXPECT_EQ(t.dims(), (std::array<std::int64_t, 3>{11, 8, 8}));
    EXPECT_NEAR(t.spacing().x, 0.25, 1e-12);
    EXPECT_FLOAT_EQ(static_cast<float>(t.value(7, 7, 7)), 3.0f);   // in the tile
    EXPECT_FLOAT_EQ(static_cast<float>(t.value(10, 1, 1)), 4.0f);  // the voxel
    EXPECT_FLOAT_EQ(static_cast<float>(t.value(9, 7, 7)), 0.5f);   // background
    expect_matches_grid(t, *temperature, openvdb::Coord(0));

    expect_error([&] { read_vdb(dir / "m.vdb", "vel"); }, dir / "m.vdb", {"'vel'", "vec3s", "float"});
    expect_error([&] { read_vdb(dir / "m.vdb", "flags"); }, dir / "m.vdb", {"'flags'", "int32"});
    expect_error([&] { read_vdb(dir / "m.vdb", "smoke"); }, dir / "m.vdb",
                 {"no grid named 'smoke'", "'density' (float)", "'temperature' (float)", "'vel' (vec3s)",
                  "'flags' (int32)"});
    // The default grid is "density".
    EXPECT_EQ(read_vdb(dir / "m.vdb").dims(), (std::array<std::int64_t, 3>{4, 5, 6}));
}

TEST(VdbReader, ThinGridsArePaddedWithTheBackground) {
    TempDir dir;
    auto one = openvdb::FloatGrid::create(0.25f);
    one->setName("density");
    one->tree().setValue(openvdb::Coord(-3, 4, 100), 2.0f);
    write_vdb(dir / "one.vdb", {one});
    WarningCapture warnings;
    const Volume v = read_vdb(dir / "one.vdb");
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{2, 2, 2}));
    EXPECT_FLOAT_EQ(static_cast<float>(v.value(0, 0, 0)), 2.0f);
    for (std::int64_t n = 1; n < 8; ++n) EXPECT_FLOAT_EQ(static_cast<float>(v.value_linear(n)), 0.25f) << n;
    EXPECT_NEAR(v.origin().x, -3.0, 1e-12);
    EXPECT_NEAR(v.origin().z, 100.0, 1e-12);
    ASSERT_EQ(warnings.messages.size(), 1u);
    EXPECT_NE(warnings.messages[0].find("one voxel thick along x, y, z"), std::string::npos)
        << warnings.messages[0];

    // A plane 3 x 4 x 1.
    auto plane = openvdb::FloatGrid::create(0.0f);
    plane->setName("density");
    plane->tree().fill(openvdb::CoordBBox(openvdb::Coord(0, 0, 9), openvdb::Coord(2, 3, 9)), 1.0f, true);
    write_vdb(dir / "plane.vdb", {plane});
    const Volume p = read_vdb(dir / "plane.vdb");
    EXPECT_EQ(p.dims(), (std::array<std::int64_t, 3>{3, 4, 2}));
    EXPECT_FLOAT_EQ(static_cast<float>(p.value(2, 3, 0)), 1.0f);
    EXPECT_FLOAT_EQ(static_cast<float>(p.value(2, 3, 1)), 0.0f);
    EXPECT_NEAR(p.origin().z, 9.0, 1e-12);
}

TEST(VdbReader, InstancesHalfFloatsAndDuplicateNames) {
    TempDir dir;
    auto density = openvdb::FloatGrid::create(0.0f);
    density->setName("density");
    density->tree().setValue(openvdb::Coord(1, 2, 3), 1.0f / 3.0f);
    density->tree().setValue(openvdb::Coord(4, 4, 4), 0.5f);
    // A second grid sharing the tree: written as an instance (metadata and transform only).
    auto smoke = openvdb::gridPtrCast<openvdb::FloatGrid>(density->copyGrid());
    smoke->setName("smoke");
    smoke->setTransform(openvdb::math::Transform::createLinearTransform(2.0));
    // Saved as 16-bit floats.
    auto half = density->deepCopy();
    half->setName("half");
    half->setSaveFloatAsHalf(true);
    // Two grids named "other".
    auto other1 = openvdb::FloatGrid::create(0.0f);
    other1->setName("other");
    other1->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
    other1->tree().setValue(openvdb::Coord(1, 1, 1), 1.0f);
    auto other2 = other1->deepCopy();
    other2->tree().setValue(openvdb::Coord(5, 5, 5), 2.0f);
    write_vdb(dir / "i.vdb", {density, smoke, half, other1, other2});

    const auto grids = list_vdb_grids(dir / "i.vdb");
    ASSERT_EQ(grids.size(), 5u);
    EXPECT_EQ(grids[1].name, "smoke");
    EXPECT_EQ(grids[1].active_voxels, 2u);
    EXPECT_EQ(grids[1].bbox_max, (std::array<std::int64_t, 3>{4, 4, 4}));
    EXPECT_EQ(grids[2].name, "half");
    EXPECT_EQ(grids[2].type, "float");
    EXPECT_EQ(grids[3].name, "other");
    EXPECT_EQ(grids[4].name, "other");
    EXPECT_EQ(grids[3].active_voxels, 2u);
    EXPECT_EQ(grids[4].active_voxels, 3u);

    const Volume d = read_vdb(dir / "i.vdb");
    const Volume s = read_vdb(dir / "i.vdb", "smoke");
    EXPECT_EQ(s.dims(), d.dims());
    EXPECT_FLOAT_EQ(static_cast<float>(s.value(0, 0, 0)), 1.0f / 3.0f);
    EXPECT_NEAR(s.spacing().x, 2.0, 1e-12);
    EXPECT_NEAR(s.origin().x, 2.0, 1e-12);
    const Volume h = read_vdb(dir / "i.vdb", "half");
    EXPECT_NEAR(h.value(0, 0, 0), 1.0 / 3.0, 1e-3);
    EXPECT_NE(static_cast<float>(h.value(0, 0, 0)), 1.0f / 3.0f);  // rounded to 16 bits
    EXPECT_FLOAT_EQ(static_cast<float>(h.value(3, 2, 1)), 0.5f);
    EXPECT_EQ(read_vdb(dir / "i.vdb", "other").dims(), (std::array<std::int64_t, 3>{2, 2, 2}));  // the first
}

TEST(VdbReader, StreamWrittenFileWithoutGridOffsets) {
    TempDir dir;
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("density");
    grid->tree().fill(openvdb::CoordBBox(openvdb::Coord(0), openvdb::Coord(40, 30, 20)), 0.75f, true);
    grid->tree().setValue(openvdb::Coord(5, 6, 7), 0.5f);
    {
        std::ofstream out(dir / "s.vdb", std::ios::binary);
        openvdb::io::Stream(out).write(openvdb::GridPtrVec{grid});
    }
    const auto grids = list_vdb_grids(dir / "s.vdb");
    ASSERT_EQ(grids.size(), 1u);
    EXPECT_EQ(grids[0].active_voxels, 41u * 31u * 21u);
    const Volume v = read_vdb(dir / "s.vdb");
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{41, 31, 21}));
    EXPECT_FLOAT_EQ(static_cast<float>(v.value(5, 6, 7)), 0.5f);
    EXPECT_FLOAT_EQ(static_cast<float>(v.value(40, 30, 20)), 0.75f);

    // Truncated: the stream's short reads are errors, not a partial grid. (In the header, the
    // metadata and the last voxel block. A cut inside the tree topology is an error too, but
    // OpenVDB 10's RootNode::readTopology then leaks the node it was reading, which LeakSanitizer
    // reports: files with grid offsets are checked before OpenVDB reads them, these cannot be.)
    const std::string bytes = read_whole(dir / "s.vdb");
    for (std::size_t n : {std::size_t{20}, std::size_t{200}, bytes.size() - 1}) {
        SCOPED_TRACE(n);
        write_bytes(dir / "t.vdb", bytes.substr(0, n));
        expect_error([&] { read_vdb(dir / "t.vdb"); }, dir / "t.vdb", {"truncated"});
    }
}

// ================================================================ errors

TEST(VdbReaderErrors, TruncatedCloud) {
    FATHOM_REQUIRE_SHARED(kCloud);
    TempDir dir;
    const std::string bytes = read_whole(shared(kCloud));
    ASSERT_GT(bytes.size(), 4096u);
    for (std::size_t n : {std::size_t{10}, std::size_t{100}, std::size_t{1024}, bytes.size() / 4,
                          bytes.size() / 2, bytes.size() - 1}) {
        SCOPED_TRACE(n);
        const fs::path p = dir / "cloud.vdb";
        write_bytes(p, bytes.substr(0, n));
        expect_error([&] { read_vdb(p); }, p, {"truncated", "the file has " + std::to_string(n) + " bytes"});
        expect_error([&] { list_vdb_grids(p); }, p, {"truncated"});
        expect_error([&] { read_volume(p); }, p, {"truncated"});
    }
    // Shorter than the magic number.
    write_bytes(dir / "c.vdb", bytes.substr(0, 5));
    expect_error([&] { read_vdb(dir / "c.vdb"); }, dir / "c.vdb", {"not an OpenVDB file"});
}

TEST(VdbReaderErrors, NotAVdbFileMissingAndEmpty) {
    TempDir dir;
    write_bytes(dir / "text.vdb", std::string(5000, 'x'));
    expect_error([&] { read_vdb(dir / "text.vdb"); }, dir / "text.vdb", {"not an OpenVDB file"});
    expect_error([&] { list_vdb_grids(dir / "text.vdb"); }, dir / "text.vdb", {"not an OpenVDB file"});
    write_bytes(dir / "empty.vdb", "");
    expect_error([&] { read_vdb(dir / "empty.vdb"); }, dir / "empty.vdb", {"empty"});
    expect_error([&] { read_vdb(dir / "missing.vdb"); }, dir / "missing.vdb", {"does not exist"});
    expect_error([&] { list_vdb_grids(dir / "missing.vdb"); }, dir / "missing.vdb", {"does not exist"});
}

TEST(VdbReaderErrors, CorruptGridData) {
    // Grid offsets pointing outside the file, and a damaged grid body.
    FATHOM_REQUIRE_SHARED(kDragon);
    TempDir dir;
    const std::string bytes = read_whole(shared(kDragon));
    // The end offset of the first grid descriptor is the 8 bytes before its metadata; find it
    // as the file size stored little-endian.
    std::string size_le(8, '\0');
    for (int b = 0; b < 8; ++b) size_le[b] = static_cast<char>((bytes.size() >> (8 * b)) & 0xff);
    const std::size_t at = bytes.find(size_le);
    ASSERT_NE(at, std::string::npos);
    std::string bad = bytes;
    bad[at + 5] = 1;  // end offset far past the end of the file
    write_bytes(dir / "offsets.vdb", bad);
    expect_error([&] { read_vdb(dir / "offsets.vdb"); }, dir / "offsets.vdb", {"truncated", "ends at byte"});

    // Zeroed grid data: either read (garbage values are still finite floats or NaN) or an error;
    // never a crash.
    bad = bytes;
    for (std::size_t i = bytes.size() / 2; i < bytes.size() / 2 + 4000; ++i) bad[i] = '\xff';
    write_bytes(dir / "body.vdb", bad);
    try {
        (void)read_vdb(dir / "body.vdb");
    } catch (const Error& e) {
        EXPECT_NE(std::string(e.what()).find((dir / "body.vdb").string()), std::string::npos);
    }
}

TEST(VdbReaderErrors, OversizedUncompressedChunkStaysInTheReadingProcess) {
    // A blosc chunk of voxel values is stored as its size (int64), then the bytes; a negative
    // size marks the bytes as stored uncompressed. OpenVDB's io::bloscFromStream copies such a
    // chunk into the node's buffer before comparing its size with the buffer's, so a damaged size
    // overflows the heap inside OpenVDB. fathom reads in a child process: the caller gets an
    // error naming the file and its own heap is untouched (the child dies of the damage: glibc's
    // heap checks or ASan abort it). Read in this process, the file aborts the test.
    openvdb::initialize();
    if (!openvdb::io::Archive::hasBloscCompression()) GTEST_SKIP() << "OpenVDB built without Blosc";
    TempDir dir;
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("density");
    auto acc = grid->getAccessor();
    for (int i = 0; i < 10; ++i) acc.setValue(openvdb::Coord(0, i / 8, i % 8), 1.0f + static_cast<float>(i));
    for (int x = 8; x < 16; ++x)  // a full leaf after it: bytes for the overflow to copy
        for (int y = 0; y < 8; ++y)
            for (int z = 0; z < 8; ++z) acc.setValue(openvdb::Coord(x, y, z), static_cast<float>(x + y + z));
    write_vdb(dir / "good.vdb", {grid});
    const std::string bytes = read_whole(dir / "good.vdb");
    // The first leaf's chunk: its 10 active values (40 bytes), a blosc frame (version byte 2,
    // then uncompressed and compressed sizes at +4 and +12) after the int64 chunk size.
    std::size_t at = std::string::npos;
    for (std::size_t i = 0; i + 24 <= bytes.size() && at == std::string::npos; ++i) {
        std::int64_t size = 0;
        std::uint32_t raw = 0, packed = 0;
        std::memcpy(&size, bytes.data() + i, 8);
        std::memcpy(&raw, bytes.data() + i + 12, 4);
        std::memcpy(&packed, bytes.data() + i + 20, 4);
        if (size > 0 && bytes[i + 8] == 2 && raw == 40 && static_cast<std::int64_t>(packed) == size) at = i;
    }
    ASSERT_NE(at, std::string::npos) << "no blosc chunk of the first leaf in the test file";
    std::string bad = bytes;
    const std::int64_t oversized = -(40 + 1024);  // "uncompressed", 1 KiB past the buffer
    bad.replace(at, 8, reinterpret_cast<const char*>(&oversized), 8);
    write_bytes(dir / "bad.vdb", bad);

    // Which error depends on where the overflow lands in the child's heap (address-space
    // layout differs from run to run): the child dies ("OpenVDB failed reading the file: its
    // reading process was killed ...") or reads on into garbage ("truncated or corrupt ...").
    // Either way: one error naming the file.
    expect_error([&] { read_vdb(dir / "bad.vdb"); }, dir / "bad.vdb", {});
    // The process goes on: the intact file still reads, exactly.
    const Volume v = read_vdb(dir / "good.vdb");
    ASSERT_EQ(v.dims(), (std::array<std::int64_t, 3>{16, 8, 8}));
    expect_matches_grid(v, *grid, openvdb::Coord(0, 0, 0));
}

TEST(VdbReaderErrors, EmptyGridNanAndFrustum) {
    TempDir dir;
    auto empty = openvdb::FloatGrid::create(0.0f);
    empty->setName("density");
    write_vdb(dir / "empty.vdb", {empty});
    const auto grids = list_vdb_grids(dir / "empty.vdb");
    ASSERT_EQ(grids.size(), 1u);
    EXPECT_EQ(grids[0].active_voxels, 0u);
    expect_error([&] { read_vdb(dir / "empty.vdb"); }, dir / "empty.vdb", {"'density'", "no active voxels"});

    auto nan = openvdb::FloatGrid::create(0.0f);
    nan->setName("density");
    nan->tree().setValue(openvdb::Coord(0, 0, 0), 1.0f);
    nan->tree().setValue(openvdb::Coord(2, 2, 2), std::numeric_limits<float>::quiet_NaN());
    write_vdb(dir / "nan.vdb", {nan});
    expect_error([&] { read_vdb(dir / "nan.vdb"); }, dir / "nan.vdb", {"NaN"});
    nan->tree().setValue(openvdb::Coord(2, 2, 2), std::numeric_limits<float>::infinity());
    write_vdb(dir / "inf.vdb", {nan});
    expect_error([&] { read_vdb(dir / "inf.vdb"); }, dir / "inf.vdb", {"infinite"});

    auto frustum = openvdb::FloatGrid::create(0.0f);
    frustum->setName("density");
    frustum->setTransform(openvdb::math::Transform::createFrustumTransform(
        openvdb::BBoxd(openvdb::Vec3d(0, 0, 0), openvdb::Vec3d(10, 10, 10)), 0.5, 2.0, 1.0));
    frustum->tree().setValue(openvdb::Coord(1, 1, 1), 1.0f);
    frustum->tree().setValue(openvdb::Coord(2, 2, 2), 1.0f);
    write_vdb(dir / "frustum.vdb", {frustum});
    expect_error([&] { read_vdb(dir / "frustum.vdb"); }, dir / "frustum.vdb",
                 {"non-linear", "NonlinearFrustumMap"});
}

TEST(VdbReaderErrors, AbsurdBoundingBoxFailsWithoutAllocating) {
    TempDir dir;
    auto grid = openvdb::FloatGrid::create(0.0f);
    grid->setName("density");
    grid->tree().setValue(openvdb::Coord(-(1 << 20), 0, 0), 1.0f);
    grid->tree().setValue(openvdb::Coord(1 << 20, 1 << 20, 1 << 20), 1.0f);
    for (bool stats : {true, false}) {  // refused from the metadata, or after reading the tree
        write_vdb(dir / "huge.vdb", {grid}, stats);
        expect_error([&] { read_vdb(dir / "huge.vdb"); }, dir / "huge.vdb",
                     {"2097153x1048577x1048577", "limit"});
    }
    EXPECT_EQ(list_vdb_grids(dir / "huge.vdb")[0].active_voxels, 2u);
}

// OpenVDB runs in fathom's module (fathom-vdb.so), loaded on the first read:
// one clear error, exit status 1, when it is missing or not a library.
TEST(VdbReaderErrors, MissingOrBrokenModule) {
    FATHOM_REQUIRE_SHARED(kCloud);
    const TempDir d;
    { std::ofstream(d / "fathom-vdb.so") << "not a shared library"; }
    auto run = [&](const std::string& module, std::string& err) {
        const auto r =
            fathom::test::run_cli("info " + shared(kCloud).string(), d, "FATHOM_VDB_MODULE='" + module + "'");
        err = r.err;
        return r.status;
    };
    std::string err;
    EXPECT_EQ(run((d / "missing" / "fathom-vdb.so").string(), err), 1);
    EXPECT_NE(err.find("OpenVDB module"), std::string::npos) << err;
    EXPECT_NE(err.find("does not exist"), std::string::npos) << err;
    EXPECT_NE(err.find(kCloud), std::string::npos) << err;  // names the file
    EXPECT_EQ(run((d / "fathom-vdb.so").string(), err), 1);
    EXPECT_NE(err.find("cannot load fathom's " + (d / "fathom-vdb.so").string()), std::string::npos) << err;
    EXPECT_EQ(std::count(err.begin(), err.end(), '\n'), 1) << err;  // one line
    EXPECT_EQ(run("", err), 0) << err;                              // unset: found beside the executable
}
