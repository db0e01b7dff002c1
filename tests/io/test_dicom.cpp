// DICOM series reader (GDCM): the real MR series and CPTAC scouts from the
// shared data, and small files written here (explicit VR little endian) for
// placement, rescale, multi-frame and every error path.
#include <algorithm>
#include <array>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <fstream>
#include <map>
#include <optional>
#include <string>
#include <vector>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/io.h"

#include "test_util.h"

using namespace fathom;
using fathom::test::expect_error;
using fathom::test::TempDir;
namespace fs = std::filesystem;

namespace {

// ---------------------------------------------------------------- file helpers

void write_file(const fs::path& p, const std::string& bytes) {
    std::ofstream f(p, std::ios::binary);
    f.write(bytes.data(), static_cast<std::streamsize>(bytes.size()));
    ASSERT_TRUE(f.good()) << p;
}

std::string read_whole(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    return {std::istreambuf_iterator<char>(f), std::istreambuf_iterator<char>()};
}

std::string le16(std::uint32_t v) {
    return {static_cast<char>(v & 0xff), static_cast<char>((v >> 8) & 0xff)};
}
std::string le32(std::uint32_t v) {
    return le16(v & 0xffff) + le16(v >> 16);
}

/// Replaces the value of the first element (group, element) in a DICOM file's
/// bytes (implicit or explicit VR little endian) by `value`, padded with `pad`
/// to the old length (it must not be longer): the file stays valid.
void patch_element(std::string& bytes, std::uint16_t group, std::uint16_t element, std::string value,
                   char pad = ' ') {
    const std::string tag = le16(group) + le16(element);
    std::size_t at = bytes.find(tag, 132);
    ASSERT_NE(at, std::string::npos) << "tag not found";
    std::size_t value_at = 0, length = 0;
    const bool explicit_vr = std::isupper(static_cast<unsigned char>(bytes[at + 4])) &&
                             std::isupper(static_cast<unsigned char>(bytes[at + 5]));
    if (explicit_vr) {
        length = static_cast<unsigned char>(bytes[at + 6]) | (static_cast<unsigned char>(bytes[at + 7]) << 8);
        value_at = at + 8;
    } else {
        std::uint32_t n = 0;
        std::memcpy(&n, bytes.data() + at + 4, 4);
        length = n;
        value_at = at + 8;
    }
    ASSERT_LE(value.size(), length) << "the patch must not grow the value";
    value.resize(length, pad);
    bytes.replace(value_at, length, value);
}

/// A value string padded with spaces to n characters.
std::string padded(std::string s, std::size_t n) {
    s.resize(n, ' ');
    return s;
}

// ---------------------------------------------------------------- a small DICOM writer

/// Data set elements in explicit VR little (or big) endian, kept in tag order.
class Dcm {
public:
    explicit Dcm(bool big_endian = false) : big_(big_endian) {}
    Dcm& str(std::uint16_t g, std::uint16_t e, const std::string& vr, std::string v) {
        if (v.size() % 2 != 0) v.push_back(vr == "UI" ? '\0' : ' ');
        return raw(g, e, vr, v);
    }
    Dcm& us(std::uint16_t g, std::uint16_t e, std::uint16_t v) { return raw(g, e, "US", u16(v)); }
    Dcm& seq(std::uint16_t g, std::uint16_t e, const std::vector<Dcm>& items) {
        std::string v;
        for (const auto& item : items) {
            const std::string body = item.body();
            v += u16(0xfffe) + u16(0xe000) + u32(static_cast<std::uint32_t>(body.size())) + body;
        }
        return raw(g, e, "SQ", v);
    }
    Dcm& pixels(const std::string& bytes) { return raw(0x7fe0, 0x0010, "OW", bytes); }
    Dcm& erase(std::uint16_t g, std::uint16_t e) {
        elements_.erase((std::uint32_t{g} << 16) | e);
        return *this;
    }

    [[nodiscard]] std::string body() const {
        std::string out;
        for (const auto& [tag, bytes] : elements_) out += bytes;
        return out;
    }
    /// A Part 10 file: preamble, "DICM", file meta group, data set.
    [[nodiscard]] std::string file(const std::string& sop_class) const {
        Dcm meta;
        meta.raw(0x0002, 0x0001, "OB", std::string("\0\1", 2));
        meta.str(0x0002, 0x0002, "UI", sop_class);
        meta.str(0x0002, 0x0003, "UI", "1.2.3.4.5.6.7");
        meta.str(0x0002, 0x0010, "UI", big_ ? "1.2.840.10008.1.2.2" : "1.2.840.10008.1.2.1");
        const std::string m = meta.body();
        Dcm length;
        length.raw(0x0002, 0x0000, "UL", le32(static_cast<std::uint32_t>(m.size())));
        return std::string(128, '\0') + "DICM" + length.body() + m + body();
    }

private:
    Dcm& raw(std::uint16_t g, std::uint16_t e, const std::string& vr, const std::string& v) {
        std::string el = u16(g) + u16(e) + vr;
        if (vr == "OB" || vr == "OW" || vr == "SQ" || vr == "UN" || vr == "UT")
            el += u16(0) + u32(static_cast<std::uint32_t>(v.size()));
        else
            el += u16(static_cast<std::uint32_t>(v.size()));
        elements_[(std::uint32_t{g} << 16) | e] = el + v;
        return *this;
    }
    [[nodiscard]] std::string u16(std::uint32_t v) const {
        std::string s = le16(v);
        if (big_) std::swap(s[0], s[1]);
        return s;
    }
    [[nodiscard]] std::string u32(std::uint32_t v) const {
        std::string s = le32(v);
        if (big_) std::reverse(s.begin(), s.end());
        return s;
    }
    bool big_ = false;  // the file meta group is always little endian (a default Dcm)
    std::map<std::uint32_t, std::string> elements_;
};

constexpr const char* kMrClass = "1.2.840.10008.5.1.4.1.1.4";
constexpr const char* kCtClass = "1.2.840.10008.5.1.4.1.1.2";
constexpr const char* kEnhancedMrClass = "1.2.840.10008.5.1.4.1.1.4.1";

std::string ds3(const Vec3& p) {
    char buf[128];
    std::snprintf(buf, sizeof buf, "%.6g\\%.6g\\%.6g", p.x, p.y, p.z);
    return buf;
}

/// One synthetic slice.
struct SliceSpec {
    int rows = 3, columns = 4;
    std::string uid = "1.2.826.0.1.3680043.2.1125.1";
    std::string description = "synthetic";
    std::optional<Vec3> position = Vec3{0, 0, 0};
    std::string orientation = "1\\0\\0\\0\\1\\0";
    std::string spacing = "0.5\\0.25";  // Δrow \ Δcolumn
    int bits_allocated = 16, bits_stored = 16, pixel_representation = 0;
    std::string photometric = "MONOCHROME2";
    int samples = 1;
    std::optional<double> slope, intercept;
    std::vector<std::int64_t> values;  // rows · columns (· frames), stored as bits_allocated
    bool big_endian = false;           // explicit VR big endian transfer syntax
};

std::string pixel_bytes(const std::vector<std::int64_t>& values, int bits, bool big_endian) {
    std::string out;
    for (auto v : values) {
        const auto u = static_cast<std::uint64_t>(v);
        for (int b = 0; b < bits / 8; ++b) {
            const int byte = big_endian ? bits / 8 - 1 - b : b;
            out.push_back(static_cast<char>((u >> (8 * byte)) & 0xff));
        }
    }
    return out;
}

Dcm image(const SliceSpec& s) {
    Dcm d(s.big_endian);
    d.str(0x0008, 0x0016, "UI", kMrClass)
        .str(0x0008, 0x0018, "UI", "1.2.3.4.5.6.7")
        .str(0x0008, 0x0060, "CS", "MR")
        .str(0x0008, 0x103e, "LO", s.description)
        .str(0x0020, 0x000d, "UI", "1.2.826.0.1.3680043.2.1125.9")
        .str(0x0020, 0x000e, "UI", s.uid)
        .str(0x0020, 0x0037, "DS", s.orientation)
        .us(0x0028, 0x0002, static_cast<std::uint16_t>(s.samples))
        .str(0x0028, 0x0004, "CS", s.photometric)
        .us(0x0028, 0x0010, static_cast<std::uint16_t>(s.rows))
        .us(0x0028, 0x0011, static_cast<std::uint16_t>(s.columns))
        .str(0x0028, 0x0030, "DS", s.spacing)
        .us(0x0028, 0x0100, static_cast<std::uint16_t>(s.bits_allocated))
        .us(0x0028, 0x0101, static_cast<std::uint16_t>(s.bits_stored))
        .us(0x0028, 0x0102, static_cast<std::uint16_t>(s.bits_stored - 1))
        .us(0x0028, 0x0103, static_cast<std::uint16_t>(s.pixel_representation));
    if (s.position) d.str(0x0020, 0x0032, "DS", ds3(*s.position));
    if (s.samples != 1) d.us(0x0028, 0x0006, 0);
    if (s.slope) d.str(0x0028, 0x1053, "DS", std::to_string(*s.slope));
    if (s.intercept) d.str(0x0028, 0x1052, "DS", std::to_string(*s.intercept));
    std::vector<std::int64_t> values = s.values;
    const std::size_t n = static_cast<std::size_t>(s.rows * s.columns * s.samples);
    if (values.empty())
        for (std::size_t i = 0; i < n; ++i) values.push_back(static_cast<std::int64_t>(i));
    d.pixels(pixel_bytes(values, s.bits_allocated, s.big_endian));
    return d;
}

void write_slice(const fs::path& p, const SliceSpec& s, const char* sop_class = kMrClass) {
    write_file(p, image(s).file(sop_class));
}

/// A stack of n slices along +z (step `step`, first at z0) in dir; slice k holds values 100·k + i.
void write_stack(const fs::path& dir, int n, double step = 2.0, double z0 = 0, SliceSpec base = {}) {
    fs::create_directories(dir);
    for (int k = 0; k < n; ++k) {
        SliceSpec s = base;
        s.position = Vec3{-10, 20, z0 + step * k};
        s.values.clear();
        for (int i = 0; i < s.rows * s.columns; ++i) s.values.push_back(100 * k + i);
        write_slice(dir / ("s" + std::to_string(k) + ".dcm"), s);
    }
}

ReadOptions series_option(const std::string& uid) {
    ReadOptions o;
    o.series = uid;
    return o;
}

// ---------------------------------------------------------------- the shared data, unpacked once

const char* kVssegTar = "mri_vsseg_dicom/vs-seg-001_t1_dicom_512x512x120.tar.gz";
const char* kCptacZip = "sim_and_small_vtkdata/dicom_stack_cptac/data.zip";
const char* kVssegUid = "1.3.6.1.4.1.14519.5.2.1.149357697745643823053302398129943470751";
constexpr std::int64_t kSliceBytes = 512 * 512 * 2;

class DicomShared : public ::testing::Test {
protected:
    static void SetUpTestSuite() {
        root_ = fs::temp_directory_path() / ("fathom_test_dicom_" + std::to_string(::getpid()));
        fs::remove_all(root_);
        fs::create_directories(root_ / "vs");
        fs::create_directories(root_ / "cptac");
        const fs::path tar = fathom::test::shared_data() / kVssegTar;
        if (fs::exists(tar)) {
            const std::string cmd = "tar -xzf '" + tar.string() + "' -C '" + (root_ / "vs").string() + "'";
            if (std::system(cmd.c_str()) == 0 && fs::exists(root_ / "vs" / "vsseg" / "1-120.dcm"))
                vsseg_ = root_ / "vs" / "vsseg";
        }
        const fs::path zip = fathom::test::shared_data() / kCptacZip;
        if (fs::exists(zip)) {
            const std::string cmd =
                "unzip -q -o '" + zip.string() + "' -d '" + (root_ / "cptac").string() + "' >/dev/null 2>&1";
            if (std::system(cmd.c_str()) == 0 && fs::exists(root_ / "cptac" / "data" / "1-3.dcm"))
                cptac_ = root_ / "cptac" / "data";
        }
    }
    static void TearDownTestSuite() {
        std::error_code ec;
        fs::remove_all(root_, ec);
    }
    void SetUp() override {
        FATHOM_REQUIRE_SHARED(kVssegTar);
        ASSERT_FALSE(vsseg_.empty()) << "could not unpack " << kVssegTar << " with tar";
    }

    static fs::path slice(int k) {  // 1-based, as the files are named
        char name[32];
        std::snprintf(name, sizeof name, "1-%03d.dcm", k);
        return vsseg_ / name;
    }
    /// Copies the series into dir, leaving out `skip` (1-based, 0: none).
    static void copy_series(const fs::path& dir, int skip = 0) {
        fs::create_directories(dir);
        for (int k = 1; k <= 120; ++k)
            if (k != skip) fs::copy_file(slice(k), dir / slice(k).filename());
    }

    static inline fs::path root_, vsseg_, cptac_;
};

TEST_F(DicomShared, ListsOneSeriesWithoutDecoding) {
    const auto t0 = std::chrono::steady_clock::now();
    const auto series = list_dicom_series(vsseg_);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    ASSERT_EQ(series.size(), 1u);
    EXPECT_EQ(series[0].uid, kVssegUid);
    EXPECT_EQ(series[0].description, "t1_mpr_tra_gk_v4");
    EXPECT_EQ(series[0].modality, "MR");
    EXPECT_EQ(series[0].rows, 512);
    EXPECT_EQ(series[0].columns, 512);
    EXPECT_EQ(series[0].files.size(), 120u);
    EXPECT_LT(seconds, 5.0) << "listing reads headers only";
    // One file lists its own series, with that one file.
    const auto one = list_dicom_series(slice(7));
    ASSERT_EQ(one.size(), 1u);
    EXPECT_EQ(one[0].uid, kVssegUid);
    ASSERT_EQ(one[0].files.size(), 1u);
    EXPECT_EQ(one[0].files[0], slice(7));
}

TEST_F(DicomShared, ReadsTheSeriesSortedAndPlaced) {
    const auto t0 = std::chrono::steady_clock::now();
    const Volume v = read_dicom(vsseg_);
    const double seconds = std::chrono::duration<double>(std::chrono::steady_clock::now() - t0).count();
    std::printf("read 120 slices of 512x512 in %.3f s\n", seconds);
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{512, 512, 120}));
    EXPECT_EQ(v.dtype(), DType::u16);
    EXPECT_NEAR(v.spacing().x, 0.41015625, 1e-9);
    EXPECT_NEAR(v.spacing().y, 0.41015625, 1e-9);
    EXPECT_NEAR(v.spacing().z, 1.5, 1e-6);  // from the positions (SliceThickness is also 1.5)
    // origin = ImagePositionPatient of 1-001.dcm, the lowest slice.
    EXPECT_NEAR(v.origin().x, -106.32680907019, 1e-9);
    EXPECT_NEAR(v.origin().y, -123.07443807356, 1e-9);
    EXPECT_NEAR(v.origin().z, -92.000669002533, 1e-9);
    // Axial: i along +x (L), j along +y (P), k along +z (S).
    EXPECT_NEAR(v.axes().column(0).x, 0.41015625, 1e-9);
    EXPECT_NEAR(v.axes().column(1).y, 0.41015625, 1e-9);
    EXPECT_NEAR(v.axes().column(2).z, 1.5, 1e-6);
    EXPECT_NEAR(std::abs(v.axes().column(2).x) + std::abs(v.axes().column(2).y), 0.0, 1e-6);
    const Vec3 last = v.index_to_world({0, 0, 119});
    EXPECT_NEAR(last.z, 86.499330997467, 1e-6);  // ImagePositionPatient of 1-120.dcm
    // The stored samples of all 120 files span 0..1826 (counted from the raw
    // pixel data; the files' Largest Image Pixel Value tags are not reliable).
    EXPECT_EQ(v.value_range(), (std::array<double, 2>{0, 1826}));
    // Slice k is file 1-(k+1).dcm (positions increase along the normal +z);
    // uncompressed implicit VR: the pixel data are the file's last bytes.
    for (int k : {0, 1, 59, 118, 119}) {
        const std::string file = read_whole(slice(k + 1));
        ASSERT_GT(file.size(), static_cast<std::size_t>(kSliceBytes));
        EXPECT_EQ(
            std::memcmp(v.bytes() + k * kSliceBytes, file.data() + file.size() - kSliceBytes, kSliceBytes), 0)
            << "slice " << k;
    }
    EXPECT_LT(seconds, 10.0);
}

TEST_F(DicomShared, FileNamesDoNotDecideTheOrder) {
    TempDir dir;
    // Names in reverse order of position, in nested folders.
    for (int k = 1; k <= 120; ++k) {
        const fs::path sub = dir / (k % 2 ? "odd" : "even");
        fs::create_directories(sub);
        fs::copy_file(slice(k), sub / ("img" + std::to_string(1000 - k)));
    }
    const Volume a = read_dicom(vsseg_);
    const Volume b = read_dicom(dir.path());
    ASSERT_EQ(b.dims(), a.dims());
    EXPECT_EQ(b.origin(), a.origin());
    EXPECT_EQ(std::memcmp(a.bytes(), b.bytes(), a.size_bytes()), 0);
    // An explicit, shuffled list of files gives the same volume.
    std::vector<fs::path> files;
    for (int k : {5, 3, 1, 2, 4}) files.push_back(slice(k));
    const Volume c = read_dicom_files(files, "five slices");
    EXPECT_EQ(c.dims(), (std::array<std::int64_t, 3>{512, 512, 5}));
    EXPECT_EQ(std::memcmp(a.bytes(), c.bytes(), c.size_bytes()), 0);
}

TEST_F(DicomShared, ReadVolumeDispatch) {
    const Volume v = read_volume(vsseg_);
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{512, 512, 120}));
    const Volume w = read_volume(vsseg_, series_option(kVssegUid));
    EXPECT_EQ(w.dims(), v.dims());
    expect_error(
        [&] { read_volume(vsseg_, series_option("1.2.3")); }, vsseg_,
        {"no DICOM series with SeriesInstanceUID 1.2.3", kVssegUid, "t1_mpr_tra_gk_v4", "120 files"});
    // One file is that file alone: one slice is not a volume.
    expect_error([&] { read_volume(slice(1)); }, slice(1), {"single slice", "folder"});
    expect_error([&] { read_volume(slice(1), series_option("1.2.3")); }, slice(1),
                 {"no DICOM series with SeriesInstanceUID 1.2.3", kVssegUid});
}

TEST_F(DicomShared, NonDicomFilesAreSkipped) {
    TempDir dir;
    copy_series(dir.path());
    write_file(dir / "README.txt", "not an image\n");
    std::string garbage(4000, '\0');
    for (std::size_t i = 0; i < garbage.size(); ++i) garbage[i] = static_cast<char>((i * 7919u) >> 3);
    write_file(dir / "garbage.bin", garbage);
    write_file(dir / "empty.dcm", "");
    const auto series = list_dicom_series(dir.path());
    ASSERT_EQ(series.size(), 1u);
    EXPECT_EQ(series[0].files.size(), 120u);
    EXPECT_EQ(read_dicom(dir.path()).dims()[2], 120);
}

TEST_F(DicomShared, MissingSlice) {
    TempDir dir;
    copy_series(dir.path(), 60);
    expect_error([&] { read_dicom(dir.path()); }, dir.path(),
                 {"missing slice between", "1-059.dcm", "1-061.dcm", "1.5 mm"});
}

TEST_F(DicomShared, DuplicateSlice) {
    TempDir dir;
    copy_series(dir.path());
    fs::copy_file(slice(60), dir / "1-060-again.dcm");
    expect_error([&] { read_dicom(dir.path()); }, dir.path(),
                 {"duplicate slice position", "1-060.dcm", "1-060-again.dcm"});
}

TEST_F(DicomShared, TruncatedFile) {
    TempDir dir;
    copy_series(dir.path());
    const std::string bytes = read_whole(slice(60));
    write_file(dir / "1-060.dcm", bytes.substr(0, bytes.size() / 2));  // cut inside the pixel data
    expect_error([&] { read_dicom(dir.path()); }, dir.path(), {"1-060.dcm", "truncated"});
    write_file(dir / "1-060.dcm", bytes.substr(0, 300));  // cut inside the header
    expect_error([&] { read_dicom(dir.path()); }, dir.path(), {"1-060.dcm", "truncated"});
}

TEST_F(DicomShared, TruncatedOrCorruptHeadersAreErrorsNotCrashes) {
    // GDCM (as Debian builds it) asserts on most truncated headers; the
    // reader's own structure check must catch every cut before GDCM sees it.
    TempDir dir;
    // (file to cut, an intact neighbour of the same series)
    std::vector<std::pair<fs::path, fs::path>> pairs{{slice(60), slice(61)}};
    if (!cptac_.empty()) pairs.emplace_back(cptac_ / "1-2.dcm", cptac_ / "1-3.dcm");  // explicit VR LE
    for (const auto& [original, neighbour] : pairs) {
        const std::string bytes = read_whole(original);
        const fs::path cut = dir / "cut.dcm";
        for (std::size_t n = 0; n < 4000; n += 11) {
            write_file(cut, bytes.substr(0, n));
            expect_error([&] { read_dicom_files({cut, neighbour}, "list"); }, "list", {"cut.dcm"});
        }
        for (std::size_t n = 4000; n < bytes.size(); n += 50021) {
            write_file(cut, bytes.substr(0, n));
            expect_error(
                [&] {
                    read_dicom_files({cut, neighbour}, "list");
                },
                "list", {"cut.dcm", "truncated"});
        }
        // Four 0xFF bytes anywhere in the header: a clear error or a volume, never a crash.
        int errors = 0;
        ::testing::internal::CaptureStderr();  // GDCM's own complaints are silenced
        for (std::size_t at = 0; at < 3600; at += 19) {
            std::string bad = bytes;
            for (std::size_t q = at; q < at + 4; ++q) bad[q] = static_cast<char>(0xff);
            write_file(cut, bad);
            try {
                (void)read_dicom_files({cut, neighbour}, "list");
            } catch (const Error& e) {
                ++errors;
                EXPECT_EQ(e.subject(), "list");
            }
        }
        EXPECT_EQ(::testing::internal::GetCapturedStderr(), "");
        EXPECT_GT(errors, 30) << original;
    }
}

TEST_F(DicomShared, UnevenSpacingAndMixedOrientation) {
    {
        TempDir dir;
        copy_series(dir.path());
        std::string bytes = read_whole(slice(60));
        // z = -3.500669002533 → -3.000669002533: 1 mm from the slice below, 2 mm from the one above.
        const std::string old_pos = "-106.32680907019\\-123.07443807356\\-3.500669002533";
        ASSERT_NE(bytes.find(old_pos), std::string::npos);
        patch_element(bytes, 0x0020, 0x0032,
                      padded("-106.32680907019\\-123.07443807356\\-3.000669002533", old_pos.size()));
        write_file(dir / "1-060.dcm", bytes);
        expect_error([&] { read_dicom(dir.path()); }, dir.path(), {"uneven slice spacing", "1-060.dcm"});
    }
    {
        TempDir dir;
        for (int k = 1; k <= 10; ++k) fs::copy_file(slice(k), dir / slice(k).filename());
        std::string bytes = read_whole(slice(5));
        patch_element(bytes, 0x0020, 0x0037, padded("0\\1\\0\\0\\0\\-1", 36));  // sagittal
        write_file(dir / "1-005.dcm", bytes);
        expect_error([&] { read_dicom(dir.path()); }, dir.path(), {"mixed orientations", "1-005.dcm"});
    }
}

TEST_F(DicomShared, TwoSeriesInOneFolder) {
    TempDir dir;
    copy_series(dir / "a");
    // A second series: 10 slices with another SeriesInstanceUID and description.
    std::string other_uid = kVssegUid;
    other_uid.back() = '2';
    fs::create_directories(dir / "b");
    for (int k = 11; k <= 20; ++k) {
        std::string bytes = read_whole(slice(k));
        patch_element(bytes, 0x0020, 0x000e, other_uid, '\0');
        patch_element(bytes, 0x0008, 0x103e, "t1_mpr_tra_COPY2");
        write_file(dir / "b" / slice(k).filename(), bytes);
    }
    const auto series = list_dicom_series(dir.path());
    ASSERT_EQ(series.size(), 2u);
    EXPECT_EQ(series[0].uid, kVssegUid);
    EXPECT_EQ(series[0].files.size(), 120u);
    EXPECT_EQ(series[1].uid, other_uid);
    EXPECT_EQ(series[1].description, "t1_mpr_tra_COPY2");
    EXPECT_EQ(series[1].files.size(), 10u);
    expect_error([&] { read_dicom(dir.path()); }, dir.path(),
                 {"2 DICOM series", "choose one with --series UID", kVssegUid, other_uid, "120 files",
                  "10 files", "t1_mpr_tra_COPY2"});
    const Volume a = read_dicom(dir.path(), kVssegUid);
    EXPECT_EQ(a.dims()[2], 120);
    const Volume b = read_volume(dir.path(), series_option(other_uid));
    EXPECT_EQ(b.dims(), (std::array<std::int64_t, 3>{512, 512, 10}));
    EXPECT_NEAR(b.origin().z, -92.000669002533 + 10 * 1.5, 1e-6);
    EXPECT_EQ(std::memcmp(a.bytes() + 10 * kSliceBytes, b.bytes(), b.size_bytes()), 0);
    expect_error([&] { read_dicom(dir.path(), "1.2.3.4"); }, dir.path(),
                 {"no DICOM series with SeriesInstanceUID 1.2.3.4", kVssegUid, other_uid});
    // An explicit list mixing the two series is refused.
    expect_error(
        [&] {
            read_dicom_files({slice(1), slice(2), dir / "b" / "1-011.dcm"}, "my list");
        },
        "my list", {"2 DICOM series"});
}

TEST_F(DicomShared, CptacScoutsAreThreeParallelSlices) {
    if (cptac_.empty()) GTEST_SKIP() << "could not unpack " << kCptacZip << " (unzip missing?)";
    // Three axial "AX SCOUT" images of one series, 12 mm apart (z = 12, 0, -12).
    const auto series = list_dicom_series(cptac_);
    ASSERT_EQ(series.size(), 1u);
    EXPECT_EQ(series[0].description, "AX SCOUT");
    EXPECT_EQ(series[0].modality, "MR");
    EXPECT_EQ(series[0].files.size(), 3u);
    const Volume v = read_dicom(cptac_);
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{512, 512, 3}));
    EXPECT_EQ(v.dtype(), DType::u16);
    EXPECT_NEAR(v.spacing().x, 0.9765625, 1e-9);
    EXPECT_NEAR(v.spacing().z, 12.0, 1e-9);
    EXPECT_EQ(v.origin(), (Vec3{-250, -250, -12}));
    EXPECT_EQ(v.value_range(), (std::array<double, 2>{0, 346}));  // the files' Largest Image Pixel Value
    // Sorted by position: slice 0 is 1-3.dcm (z = -12), slice 2 is 1-1.dcm (z = 12).
    for (auto [k, name] : {std::pair{0, "1-3.dcm"}, std::pair{2, "1-1.dcm"}}) {
        const std::string file = read_whole(cptac_ / name);
        EXPECT_EQ(
            std::memcmp(v.bytes() + k * kSliceBytes, file.data() + file.size() - kSliceBytes, kSliceBytes), 0)
            << name;
    }
    // Together with the MR series: two series, and a mixed list is refused.
    TempDir dir;
    fs::copy(cptac_, dir / "scouts");
    for (int k = 1; k <= 4; ++k) fs::copy_file(slice(k), dir / slice(k).filename());
    expect_error([&] { read_dicom(dir.path()); }, dir.path(), {"2 DICOM series", "AX SCOUT", "3 files"});
    EXPECT_EQ(read_dicom(dir.path(), series[0].uid).dims()[2], 3);
}

// ================================================================ synthetic files

TEST(DicomSynthetic, RotatedPlacementAndRescale) {
    TempDir dir;
    // Sagittal slices: rows run along +y (A→P), columns down −z; normal r × c = −x.
    // Positions x = 10, 7, 4: sorted along the normal, x decreases.
    const std::vector<double> xs{4, 10, 7};
    for (std::size_t f = 0; f < xs.size(); ++f) {
        SliceSpec s;
        s.orientation = "0\\1\\0\\0\\0\\-1";
        s.position = Vec3{xs[f], -5, 30};
        s.pixel_representation = 1;
        s.slope = 2;
        s.intercept = -1024;
        s.values.clear();
        for (int i = 0; i < 12; ++i) s.values.push_back(static_cast<std::int64_t>(xs[f]) * 10 + i - 50);
        write_slice(dir / ("x" + std::to_string(f) + ".dcm"), s, kCtClass);
    }
    const Volume v = read_dicom(dir.path());
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{4, 3, 3}));
    EXPECT_EQ(v.dtype(), DType::f32);  // rescaled
    EXPECT_EQ(v.origin(), (Vec3{10, -5, 30}));
    const Mat3& m = v.axes();
    // i: row direction · Δcolumn (0.25), j: column direction · Δrow (0.5), k: normal · 3.
    EXPECT_NEAR(m.column(0).y, 0.25, 1e-12);
    EXPECT_NEAR(m.column(1).z, -0.5, 1e-12);
    EXPECT_NEAR(m.column(2).x, -3, 1e-12);
    EXPECT_NEAR(std::abs(m.column(0).x) + std::abs(m.column(0).z) + std::abs(m.column(1).x) +
                    std::abs(m.column(1).y) + std::abs(m.column(2).y) + std::abs(m.column(2).z),
                0, 1e-12);
    // Pixel (i, j) of the slice at x: (10x + i + 4j − 50)·2 − 1024, at (x, −5 + 0.25i, 30 − 0.5j).
    for (int k = 0; k < 3; ++k) {
        const double x = 10 - 3 * k;
        for (int j = 0; j < 3; ++j)
            for (int i = 0; i < 4; ++i) {
                EXPECT_DOUBLE_EQ(v.value(i, j, k), (10 * x + i + 4 * j - 50) * 2 - 1024);
                const Vec3 p = v.index_to_world({double(i), double(j), double(k)});
                EXPECT_NEAR(p.x, x, 1e-12);
                EXPECT_NEAR(p.y, -5 + 0.25 * i, 1e-12);
                EXPECT_NEAR(p.z, 30 - 0.5 * j, 1e-12);
            }
    }
}

TEST(DicomSynthetic, StoredTypesKeptWithIdentityRescale) {
    struct Case {
        int bits, pr;
        DType type;
        std::int64_t value;
    };
    for (const Case c : {Case{8, 0, DType::u8, 200}, Case{8, 1, DType::i8, -100},
                         Case{16, 0, DType::u16, 60000}, Case{16, 1, DType::i16, -30000},
                         Case{32, 0, DType::u32, 4000000000}, Case{32, 1, DType::i32, -2000000000}}) {
        TempDir dir;
        SliceSpec base;
        base.bits_allocated = base.bits_stored = c.bits;
        base.pixel_representation = c.pr;
        base.slope = 1;
        base.intercept = 0;
        for (int k = 0; k < 2; ++k) {
            SliceSpec s = base;
            s.position = Vec3{0, 0, double(k)};
            s.values.assign(12, k == 0 ? c.value : 1);
            write_slice(dir / ("s" + std::to_string(k) + ".dcm"), s);
        }
        const Volume v = read_dicom(dir.path());
        EXPECT_EQ(v.dtype(), c.type) << c.bits << " bits";
        EXPECT_EQ(v.value(3, 2, 0), static_cast<double>(c.value)) << c.bits << " bits";
        EXPECT_EQ(v.value(0, 0, 1), 1.0);
    }
}

TEST(DicomSynthetic, ExplicitBigEndian) {
    TempDir dir;
    SliceSpec base;
    base.big_endian = true;
    base.pixel_representation = 1;
    base.spacing = "0.75\\0.5";
    write_stack(dir.path(), 3, 2.5, -4, base);  // slice k holds 100·k + i
    const Volume v = read_dicom(dir.path());
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{4, 3, 3}));
    EXPECT_EQ(v.dtype(), DType::i16);
    EXPECT_EQ(v.value(1, 0, 0), 1);
    EXPECT_EQ(v.value(3, 2, 2), 211);
    EXPECT_EQ(v.value(2, 1, 1), 106);
    EXPECT_NEAR(v.spacing().x, 0.5, 1e-12);
    EXPECT_NEAR(v.spacing().y, 0.75, 1e-12);
    EXPECT_NEAR(v.spacing().z, 2.5, 1e-12);
    EXPECT_EQ(v.origin(), (Vec3{-10, 20, -4}));
    const auto series = list_dicom_series(dir.path());
    ASSERT_EQ(series.size(), 1u);
    EXPECT_EQ(series[0].rows, 3);
    EXPECT_EQ(series[0].columns, 4);
}

TEST(DicomSynthetic, BitsAboveBitsStored) {
    TempDir dir;
    // 12 bits stored in 16: unsigned values with junk above bit 11 are masked,
    // signed ones sign-extended from bit 11.
    for (int pr : {0, 1}) {
        const fs::path sub = dir / std::to_string(pr);
        fs::create_directories(sub);
        for (int k = 0; k < 2; ++k) {
            SliceSpec s;
            s.bits_stored = 12;
            s.pixel_representation = pr;
            s.position = Vec3{0, 0, double(k)};
            s.values.assign(12, 0xF123);
            s.values[1] = 0x0FFF;
            write_slice(sub / ("s" + std::to_string(k) + ".dcm"), s);
        }
        const Volume v = read_dicom(sub);
        if (pr == 0) {
            EXPECT_EQ(v.dtype(), DType::u16);
            EXPECT_EQ(v.value(0, 0, 0), 0x123);
            EXPECT_EQ(v.value(1, 0, 0), 0xFFF);
        } else {
            EXPECT_EQ(v.dtype(), DType::i16);
            EXPECT_EQ(v.value(0, 0, 0), 0x123);
            EXPECT_EQ(v.value(1, 0, 1), -1);
        }
    }
}

TEST(DicomSynthetic, PerSliceRescale) {
    TempDir dir;
    for (int k = 0; k < 3; ++k) {
        SliceSpec s;
        s.position = Vec3{0, 0, 5.0 * k};
        s.slope = 1.0 + k;  // 1, 2, 3
        s.intercept = 10.0 * k;
        s.values.assign(12, 7);
        write_slice(dir / ("s" + std::to_string(k) + ".dcm"), s);
    }
    const Volume v = read_dicom(dir.path());
    EXPECT_EQ(v.dtype(), DType::f32);
    EXPECT_EQ(v.value(2, 1, 0), 7.0);
    EXPECT_EQ(v.value(2, 1, 1), 24.0);
    EXPECT_EQ(v.value(2, 1, 2), 41.0);
    EXPECT_NEAR(v.spacing().z, 5.0, 1e-12);
}

TEST(DicomSynthetic, GantryTiltIsHonoured) {
    TempDir dir;
    // Axial slices whose positions move 0.5 mm in y per 2 mm in z (a tilted gantry).
    for (int k = 0; k < 4; ++k) {
        SliceSpec s;
        s.position = Vec3{1, 2 + 0.5 * k, 3 + 2.0 * k};
        write_slice(dir / ("s" + std::to_string(k) + ".dcm"), s);
    }
    const Volume v = read_dicom(dir.path());
    EXPECT_EQ(v.dims()[2], 4);
    const Vec3 k_axis = v.axes().column(2);
    EXPECT_NEAR(k_axis.x, 0, 1e-12);
    EXPECT_NEAR(k_axis.y, 0.5, 1e-12);
    EXPECT_NEAR(k_axis.z, 2.0, 1e-12);
    const Vec3 p = v.index_to_world({0, 0, 3});
    EXPECT_NEAR(p.y, 3.5, 1e-12);
    EXPECT_NEAR(p.z, 9, 1e-12);
}

/// An enhanced MR file: frames in the order given by zs, shared orientation
/// and pixel measures, per-frame positions and rescale.
Dcm enhanced(const std::vector<double>& zs, bool per_frame = true) {
    SliceSpec s;
    const int frames = static_cast<int>(zs.size());
    s.position.reset();
    s.values.clear();
    for (int f = 0; f < frames; ++f)
        for (int i = 0; i < 12; ++i)
            s.values.push_back(static_cast<std::int64_t>(zs[static_cast<std::size_t>(f)]) * 100 + i);
    Dcm d = image(s);
    d.erase(0x0020, 0x0037).erase(0x0028, 0x0030);
    d.str(0x0008, 0x0016, "UI", kEnhancedMrClass).str(0x0028, 0x0008, "IS", std::to_string(frames));
    Dcm orientation, measures;
    orientation.str(0x0020, 0x0037, "DS", "1\\0\\0\\0\\1\\0");
    measures.str(0x0028, 0x0030, "DS", "0.5\\0.25");
    Dcm shared;
    shared.seq(0x0020, 0x9116, {orientation}).seq(0x0028, 0x9110, {measures});
    d.seq(0x5200, 0x9229, {shared});
    if (per_frame) {
        std::vector<Dcm> items;
        for (int f = 0; f < frames; ++f) {
            Dcm pos, scale, item;
            pos.str(0x0020, 0x0032, "DS", ds3({0, 0, zs[static_cast<std::size_t>(f)]}));
            scale.str(0x0028, 0x1052, "DS", "0").str(0x0028, 0x1053, "DS", f == 0 ? "2" : "1");
            item.seq(0x0020, 0x9113, {pos}).seq(0x0028, 0x9145, {scale});
            items.push_back(item);
        }
        d.seq(0x5200, 0x9230, items);
    }
    return d;
}

TEST(DicomSynthetic, EnhancedMultiFrame) {
    TempDir dir;
    write_file(dir / "mf.dcm", enhanced({6, 2, 4}).file(kEnhancedMrClass));
    const Volume v = read_dicom(dir / "mf.dcm");  // one file, several frames: a volume
    EXPECT_EQ(v.dims(), (std::array<std::int64_t, 3>{4, 3, 3}));
    EXPECT_EQ(v.dtype(), DType::f32);  // frame 1 has slope 2
    EXPECT_EQ(v.origin(), (Vec3{0, 0, 2}));
    EXPECT_NEAR(v.spacing().x, 0.25, 1e-12);
    EXPECT_NEAR(v.spacing().y, 0.5, 1e-12);
    EXPECT_NEAR(v.spacing().z, 2, 1e-12);
    // Slices sorted by z: frames 2 (z 2), 3 (z 4), 1 (z 6, doubled).
    EXPECT_EQ(v.value(1, 0, 0), 201);
    EXPECT_EQ(v.value(1, 0, 1), 401);
    EXPECT_EQ(v.value(1, 0, 2), 1202);
    const auto series = list_dicom_series(dir / "mf.dcm");
    ASSERT_EQ(series.size(), 1u);
    EXPECT_EQ(series[0].files.size(), 1u);
    // Frames without per-frame positions cannot be placed.
    write_file(dir / "mf.dcm", enhanced({6, 2, 4}, false).file(kEnhancedMrClass));
    expect_error([&] { read_dicom(dir / "mf.dcm"); }, dir / "mf.dcm", {"multi-frame", "not supported"});
}

// ================================================================ errors

TEST(DicomErrors, FoldersWithoutDicom) {
    TempDir dir;
    expect_error([&] { read_dicom(dir.path()); }, dir.path(), {"no DICOM files in folder"});
    expect_error([&] { list_dicom_series(dir.path()); }, dir.path(), {"no DICOM files in folder"});
    expect_error([&] { read_volume(dir.path()); }, dir.path(), {"no DICOM files in folder"});
    write_file(dir / "notes.txt", "hello\n");
    expect_error([&] { read_dicom(dir.path()); }, dir.path(),
                 {"no DICOM files in folder", "none of them DICOM"});
    expect_error([&] { read_dicom(dir / "notes.txt"); }, dir / "notes.txt", {"not a DICOM file"});
    expect_error([&] { read_dicom(dir / "absent"); }, dir / "absent", {"does not exist"});
    expect_error([&] { read_dicom_files({}, "nothing"); }, "nothing", {"no DICOM files"});
    expect_error([&] { read_dicom_files({dir / "notes.txt"}, "list"); }, "list",
                 {"notes.txt", "not a DICOM file"});
    // A DICOM file without an image (a report): no image in the folder.
    Dcm report;
    report.str(0x0008, 0x0016, "UI", "1.2.840.10008.5.1.4.1.1.88.11").str(0x0020, 0x000e, "UI", "1.2.3");
    write_file(dir / "report.dcm", report.file("1.2.840.10008.5.1.4.1.1.88.11"));
    expect_error([&] { read_dicom(dir.path()); }, dir.path(), {"no DICOM images in folder"});
}

TEST(DicomErrors, MismatchedSlices) {
    TempDir dir;
    fs::create_directories(dir / "rows");
    SliceSpec a, b;
    b.position = Vec3{0, 0, 1};
    b.rows = 4;
    write_slice(dir / "rows" / "a.dcm", a);
    write_slice(dir / "rows" / "b.dcm", b);
    expect_error([&] { read_dicom(dir / "rows"); }, dir / "rows", {"mismatched Rows", "a.dcm", "b.dcm"});

    fs::create_directories(dir / "bits");
    SliceSpec c = b;
    c.rows = 3;
    c.bits_allocated = c.bits_stored = 8;
    write_slice(dir / "bits" / "a.dcm", a);
    write_slice(dir / "bits" / "c.dcm", c);
    expect_error([&] { read_dicom(dir / "bits"); }, dir / "bits", {"mismatched BitsAllocated"});

    fs::create_directories(dir / "spacing");
    SliceSpec d = b;
    d.rows = 3;
    d.spacing = "0.5\\0.5";
    write_slice(dir / "spacing" / "a.dcm", a);
    write_slice(dir / "spacing" / "d.dcm", d);
    expect_error([&] { read_dicom(dir / "spacing"); }, dir / "spacing", {"mixed PixelSpacing"});
}

TEST(DicomErrors, GeometryProblems) {
    TempDir dir;
    // Uneven: z = 0, 1, 2.5.
    fs::create_directories(dir / "uneven");
    for (double z : {0.0, 1.0, 2.5}) {
        SliceSpec s;
        s.position = Vec3{0, 0, z};
        write_slice(dir / "uneven" / ("z" + std::to_string(z) + ".dcm"), s);
    }
    expect_error([&] { read_dicom(dir / "uneven"); }, dir / "uneven", {"uneven slice spacing"});
    // Two slices missing: z = 0, 1, 4 → "2 slices missing".
    fs::create_directories(dir / "gap");
    for (double z : {0.0, 1.0, 2.0, 5.0}) {
        SliceSpec s;
        s.position = Vec3{0, 0, z};
        write_slice(dir / "gap" / ("z" + std::to_string(z) + ".dcm"), s);
    }
    expect_error([&] { read_dicom(dir / "gap"); }, dir / "gap",
                 {"missing slice between", "2 slices missing"});
    // Positions not on a line (a slice shifted sideways).
    fs::create_directories(dir / "shift");
    for (int k = 0; k < 4; ++k) {
        SliceSpec s;
        s.position = Vec3{k == 2 ? 3.0 : 0.0, 0, double(k)};
        write_slice(dir / "shift" / ("s" + std::to_string(k) + ".dcm"), s);
    }
    expect_error([&] { read_dicom(dir / "shift"); }, dir / "shift", {"do not line up", "s2.dcm"});
    // No position.
    fs::create_directories(dir / "nopos");
    write_stack(dir / "nopos", 2);
    SliceSpec s;
    s.position.reset();
    write_slice(dir / "nopos" / "s1.dcm", s);
    expect_error([&] { read_dicom(dir / "nopos"); }, dir / "nopos", {"no ImagePositionPatient", "s1.dcm"});
    // Orientation that is not two perpendicular unit vectors.
    fs::create_directories(dir / "badiop");
    SliceSpec parallel;
    parallel.orientation = "1\\0\\0\\1\\0\\0";
    write_stack(dir / "badiop", 2, 1.0, 0, parallel);
    expect_error([&] { read_dicom(dir / "badiop"); }, dir / "badiop", {"ImageOrientationPatient"});
    // Malformed numbers.
    fs::create_directories(dir / "badpos");
    write_stack(dir / "badpos", 2);
    std::string bytes = read_whole(dir / "badpos" / "s1.dcm");
    const std::string pos = ds3({-10, 20, 2});
    patch_element(bytes, 0x0020, 0x0032, padded("-10\\20", pos.size() + pos.size() % 2));
    write_file(dir / "badpos" / "s1.dcm", bytes);
    expect_error([&] { read_dicom(dir / "badpos"); }, dir / "badpos", {"s1.dcm", "ImagePositionPatient"});
}

TEST(DicomErrors, UnsupportedAndAbsurdImages) {
    TempDir dir;
    // Colour.
    fs::create_directories(dir / "rgb");
    SliceSpec rgb;
    rgb.samples = 3;
    rgb.photometric = "RGB";
    rgb.bits_allocated = rgb.bits_stored = 8;
    for (int k = 0; k < 2; ++k) {
        rgb.position = Vec3{0, 0, double(k)};
        write_slice(dir / "rgb" / ("s" + std::to_string(k) + ".dcm"), rgb);
    }
    EXPECT_EQ(list_dicom_series(dir / "rgb").size(), 1u);  // listed, but not read
    expect_error([&] { read_dicom(dir / "rgb"); }, dir / "rgb", {"colour", "RGB", "not supported"});
    // A header claiming a huge multi-frame image.
    Dcm huge = image(SliceSpec{});
    huge.us(0x0028, 0x0010, 65535).us(0x0028, 0x0011, 65535).str(0x0028, 0x0008, "IS", "100000");
    write_file(dir / "huge.dcm", huge.file(kMrClass));
    expect_error([&] { read_dicom(dir / "huge.dcm"); }, dir / "huge.dcm", {"exceed"});
    // Headers whose Rows do not match their pixel data (3 rows stored, 300 claimed).
    fs::create_directories(dir / "short");
    write_stack(dir / "short", 2);
    for (const char* name : {"s0.dcm", "s1.dcm"}) {
        std::string bytes = read_whole(dir / "short" / name);
        patch_element(bytes, 0x0028, 0x0010, le16(300));
        write_file(dir / "short" / name, bytes);
    }
    expect_error([&] { read_dicom(dir / "short"); }, dir / "short", {"s0.dcm", "pixel data"});
}

TEST(DicomErrors, ExplicitVrWithoutMetaGroupIsRefused) {
    // Found by fuzzing: one explicit-VR UN element and no file meta group
    // made GDCM abort on an assertion.
    TempDir dir;
    write_file(dir / "raw.dcm", std::string("\x08\x00\x10\x00UN\x00\x00\x02\x00\x00\x00 ?", 14));
    expect_error([&] { read_dicom(dir / "raw.dcm"); }, dir / "raw.dcm", {"not a DICOM Part 10 file"});
    // The same element in a Part 10 file is read past (and the file has no image).
    Dcm d;
    d.str(0x0008, 0x0010, "UN", " ?");
    write_file(dir / "p10.dcm", d.file(kMrClass));
    EXPECT_THROW(read_dicom(dir / "p10.dcm"), Error);
    // Also found by fuzzing: a file meta group without the preamble, with a
    // made-up VR, made GDCM abort.
    write_file(dir / "meta.dcm", std::string("\x02\x00\x0c\x00QQ", 6) + std::string(130, '\0'));
    expect_error([&] { read_dicom(dir / "meta.dcm"); }, dir / "meta.dcm",
                 {"preamble", "not a DICOM Part 10 file"});
    std::string bad = d.file(kMrClass);
    const auto vr = bad.find("UI", 132);  // the first meta element's VR
    ASSERT_NE(vr, std::string::npos);
    bad.replace(vr, 2, "QQ");
    write_file(dir / "badvr.dcm", bad);
    expect_error([&] { read_dicom(dir / "badvr.dcm"); }, dir / "badvr.dcm", {"no valid VR"});
}

}  // namespace

// GDCM runs in fathom's DICOM module (fathom-dicom.so), loaded on the first
// DICOM read: one clear error, exit status 1, when it is missing or not a
// library; processes that read no DICOM never load it.
TEST(DicomErrors, MissingOrBrokenModule) {
    const TempDir d;
    for (int z = 0; z < 2; ++z) {
        SliceSpec s;
        s.position = Vec3{0, 0, static_cast<double>(z)};
        s.values.assign(12, 100 + z);
        write_slice(d / ("s" + std::to_string(z) + ".dcm"), s);
    }
    { std::ofstream(d / "fathom-dicom.so") << "not a shared library"; }
    auto run = [&](const std::string& args, const std::string& module, std::string& out) {
        const auto r = fathom::test::run_cli(args, d, "FATHOM_DICOM_MODULE='" + module + "'");
        out = r.err + r.out;
        return r.status;
    };
    std::string out;
    const std::string info = "info " + (d / "s0.dcm").string();
    EXPECT_EQ(run(info, (d / "missing" / "fathom-dicom.so").string(), out), 1);
    EXPECT_NE(out.find("cannot read DICOM files: fathom's DICOM module"), std::string::npos) << out;
    EXPECT_NE(out.find("does not exist"), std::string::npos) << out;
    EXPECT_NE(out.find((d / "s0.dcm").string()), std::string::npos) << out;  // names the file
    EXPECT_EQ(run(info, (d / "fathom-dicom.so").string(), out), 1);
    EXPECT_NE(out.find("cannot load fathom's " + (d / "fathom-dicom.so").string()), std::string::npos) << out;
    EXPECT_EQ(std::count(out.begin(), out.end(), '\n'), 1) << out;  // one line
    // a folder too, and unset: found beside the executable
    EXPECT_EQ(run("info " + d.path().string(), (d / "fathom-dicom.so").string(), out), 1) << out;
    EXPECT_EQ(run("info " + d.path().string(), "", out), 0) << out;
    EXPECT_NE(out.find("4 x 3 x 2"), std::string::npos) << out;
    // what reads no DICOM does not need the module
    EXPECT_EQ(run("--version", (d / "missing" / "fathom-dicom.so").string(), out), 0) << out;
}
