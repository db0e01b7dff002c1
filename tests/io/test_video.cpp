// VideoWriter (MP4, GIF through FFmpeg's libraries) and `fathom render
// --video`: valid containers, exact sizes, clear errors, no partial files.
#include <cmath>
#include <cstdlib>
#include <fstream>
#include <sstream>
#include <string>

#include <gtest/gtest.h>

#include "fathom/error.h"
#include "fathom/video.h"

#include "io/shared_library.h"
#include "test_util.h"

using namespace fathom;
using fathom::test::expect_error;
using fathom::test::TempDir;
namespace fs = std::filesystem;

namespace {

Image frame(int w, int h, int f) {
    Image im(w, h);
    for (int y = 0; y < h; ++y)
        for (int x = 0; x < w; ++x) {
            float* p = im.pixel(x, y);
            p[0] = static_cast<float>(x) / static_cast<float>(w);
            p[1] = static_cast<float>(y) / static_cast<float>(h);
            p[2] = 0.5f + 0.5f * static_cast<float>(std::sin(0.3 * f + 0.1 * x));
            p[3] = 1.0f;
        }
    return im;
}

std::string slurp(const fs::path& p) {
    std::ifstream f(p, std::ios::binary);
    std::stringstream ss;
    ss << f.rdbuf();
    return ss.str();
}

#define REQUIRE_VIDEO() \
    if (!video_supported()) GTEST_SKIP() << "built without FFmpeg"

}  // namespace

TEST(Video, Mp4IsAnIsoMediaFileWithH264OrMpeg4) {
    REQUIRE_VIDEO();
    TempDir dir;
    VideoWriter v(dir / "t.mp4", 64, 48, 12);
    for (int f = 0; f < 12; ++f) v.add(frame(64, 48, f));
    EXPECT_FALSE(fs::exists(dir / "t.mp4")) << "visible before finish()";
    v.finish();
    const std::string bytes = slurp(dir / "t.mp4");
    ASSERT_GT(bytes.size(), 500u);
    EXPECT_EQ(bytes.substr(4, 4), "ftyp");
    EXPECT_NE(bytes.find("moov"), std::string::npos);
    EXPECT_TRUE(bytes.find("avc1") != std::string::npos || bytes.find("mp4v") != std::string::npos);
}

TEST(Video, OddSizesAreRoundedDownForMp4) {
    REQUIRE_VIDEO();
    TempDir dir;
    VideoWriter v(dir / "odd.mp4", 33, 21, 24);
    v.add(frame(33, 21, 0));
    v.finish();
    EXPECT_GT(fs::file_size(dir / "odd.mp4"), 100u);
}

TEST(Video, GifLoopsAndHoldsEveryFrame) {
    REQUIRE_VIDEO();
    TempDir dir;
    VideoWriter v(dir / "t.gif", 40, 30, 10);
    for (int f = 0; f < 5; ++f) v.add(frame(40, 30, f));
    v.finish();
    const std::string bytes = slurp(dir / "t.gif");
    ASSERT_GT(bytes.size(), 13u);
    EXPECT_EQ(bytes.substr(0, 6), "GIF89a");
    EXPECT_EQ(static_cast<unsigned char>(bytes[6]) | static_cast<unsigned char>(bytes[7]) << 8, 40);
    EXPECT_EQ(static_cast<unsigned char>(bytes[8]) | static_cast<unsigned char>(bytes[9]) << 8, 30);
    EXPECT_NE(bytes.find("NETSCAPE2.0"), std::string::npos) << "no loop extension";
    // One graphic control extension (0x21 0xF9) per frame.
    int gce = 0;
    for (std::size_t i = 0; i + 1 < bytes.size(); ++i)
        if (bytes[i] == '\x21' && bytes[i + 1] == '\xF9') ++gce;
    EXPECT_GE(gce, 5);
}

TEST(Video, ErrorsNameTheFileAndLeaveNothing) {
    TempDir dir;
    if (!video_supported()) {
        expect_error([&] { VideoWriter v(dir / "x.mp4", 8, 8, 24); }, dir / "x.mp4", {"FFmpeg"});
        return;
    }
    expect_error([&] { VideoWriter v(dir / "x.avi", 8, 8, 24); }, dir / "x.avi", {".avi"});
    expect_error([&] { VideoWriter v(dir / "x.mp4", 8, 8, 0); }, dir / "x.mp4", {"frame rate"});
    expect_error([&] { VideoWriter v(dir / "no" / "x.mp4", 8, 8, 24); }, dir / "no" / "x.mp4", {});
    expect_error(
        [&] {
            VideoWriter v(dir / "y.mp4", 8, 8, 24);
            v.add(frame(9, 8, 0));
        },
        dir / "y.mp4", {"9x8"});
    expect_error(
        [&] {
            VideoWriter v(dir / "z.gif", 8, 8, 24);
            v.finish();
        },
        dir / "z.gif", {"at least one frame"});
    for (const char* n : {"x.avi", "x.mp4", "y.mp4", "z.gif"}) EXPECT_FALSE(fs::exists(dir / n)) << n;
    EXPECT_TRUE(fs::is_empty(dir.path())) << "temporary files left behind";
}

// The libraries a video needs are loaded when it is opened (dlopen): a
// missing one, or a missing function, is one error naming the file and the
// library.
TEST(Video, MissingLibrariesAreClearErrors) {
    const fs::path file = "turntable.mp4";
    expect_error([&] { io::load_library("libfathom-absent.so.1", "FFmpeg", file.string()); }, file,
                 {"cannot load FFmpeg's libfathom-absent.so.1"});
    void* libc = io::load_library("libc.so.6", "the C library", file.string());
    EXPECT_NE(io::library_function(libc, "strlen", "libc.so.6", "the C library", file.string()), nullptr);
    expect_error(
        [&] {
            io::library_function(libc, "fathom_absent_function", "libc.so.6", "the C library", file.string());
        },
        file, {"libc.so.6 has no function fathom_absent_function"});
}
