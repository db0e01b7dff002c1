// VideoWriter: MP4 (H.264) and animated GIF through FFmpeg's libraries
// (libavformat, libavcodec, libswscale), when the build found their headers
// (FATHOM_HAVE_FFMPEG); otherwise every use is a clear error. The libraries
// are loaded (dlopen) when the first video is opened, not linked: they pull
// in about 120 shared libraries (every codec FFmpeg was built with), which
// every fathom process would otherwise map and relocate at start-up.
#include <algorithm>
#include <array>
#include <cstdint>
#include <mutex>
#include <numeric>
#include <string>
#include <vector>

#include "fathom/error.h"
#include "fathom/video.h"

#include "io/atomic_file.h"
#include "io/shared_library.h"
#include "io/srgb.h"

#ifdef FATHOM_HAVE_FFMPEG
extern "C" {
#include <libavcodec/avcodec.h>
#include <libavformat/avformat.h>
#include <libavutil/imgutils.h>
#include <libavutil/log.h>
#include <libavutil/opt.h>
#include <libswscale/swscale.h>
}
#endif

namespace fathom {

namespace fs = std::filesystem;

namespace {

std::string lower_ext(const fs::path& p) {
    std::string e = p.extension().string();
    for (char& c : e) c = static_cast<char>(std::tolower(static_cast<unsigned char>(c)));
    return e;
}

/// The frame as sRGB 8-bit RGB, row 0 at the top.
std::vector<std::uint8_t> rgb8(const Image& im) {
    const std::size_t n = static_cast<std::size_t>(im.width) * static_cast<std::size_t>(im.height);
    std::vector<std::uint8_t> out(n * 3);
    for (std::size_t i = 0; i < n; ++i)
        for (int c = 0; c < 3; ++c) out[i * 3 + static_cast<std::size_t>(c)] = io::srgb8(im.rgba[i * 4 + c]);
    return out;
}

/// Median-cut palette of up to 256 colors over a 5-5-5 bit histogram, and
/// each pixel's palette index (nearest palette color of its histogram bin).
struct Quantized {
    std::array<std::uint32_t, 256> palette{};  // 0xAARRGGBB, as FFmpeg's PAL8 wants
    std::vector<std::uint8_t> index;
};

Quantized quantize(const std::vector<std::uint8_t>& rgb) {
    constexpr int kBins = 1 << 15;
    auto bin_of = [](const std::uint8_t* p) { return (p[0] >> 3) << 10 | (p[1] >> 3) << 5 | (p[2] >> 3); };
    std::vector<std::uint32_t> count(kBins, 0);
    const std::size_t n = rgb.size() / 3;
    for (std::size_t i = 0; i < n; ++i) ++count[static_cast<std::size_t>(bin_of(&rgb[i * 3]))];
    std::vector<int> bins;
    for (int b = 0; b < kBins; ++b)
        if (count[static_cast<std::size_t>(b)] > 0) bins.push_back(b);
    auto chan = [](int b, int c) { return (b >> (10 - 5 * c)) & 31; };
    // Boxes are ranges of `bins`; split the box with the widest channel at its weighted median.
    struct Box {
        std::size_t lo, hi;
    };
    std::vector<Box> boxes{{0, bins.size()}};
    while (boxes.size() < 256) {
        int best = -1, best_c = 0, best_range = 0;
        for (std::size_t k = 0; k < boxes.size(); ++k) {
            if (boxes[k].hi - boxes[k].lo < 2) continue;
            for (int c = 0; c < 3; ++c) {
                int lo = 31, hi = 0;
                for (std::size_t i = boxes[k].lo; i < boxes[k].hi; ++i) {
                    lo = std::min(lo, chan(bins[i], c));
                    hi = std::max(hi, chan(bins[i], c));
                }
                if (hi - lo > best_range) best = static_cast<int>(k), best_c = c, best_range = hi - lo;
            }
        }
        if (best < 0) break;
        Box& b = boxes[static_cast<std::size_t>(best)];
        std::sort(bins.begin() + static_cast<std::ptrdiff_t>(b.lo),
                  bins.begin() + static_cast<std::ptrdiff_t>(b.hi),
                  [&](int x, int y) { return chan(x, best_c) < chan(y, best_c); });
        std::uint64_t total = 0, acc = 0;
        for (std::size_t i = b.lo; i < b.hi; ++i) total += count[static_cast<std::size_t>(bins[i])];
        std::size_t mid = b.lo + 1;
        for (std::size_t i = b.lo; i < b.hi - 1; ++i) {
            acc += count[static_cast<std::size_t>(bins[i])];
            mid = i + 1;
            if (2 * acc >= total) break;
        }
        const Box second{mid, b.hi};
        b.hi = mid;
        boxes.push_back(second);
    }
    Quantized q;
    std::vector<std::array<double, 3>> pal;
    for (const Box& b : boxes) {
        std::array<double, 3> sum{0, 0, 0};
        double w = 0;
        for (std::size_t i = b.lo; i < b.hi; ++i) {
            const double cnt = count[static_cast<std::size_t>(bins[i])];
            for (int c = 0; c < 3; ++c) sum[c] += cnt * (chan(bins[i], c) * 8 + 4);
            w += cnt;
        }
        pal.push_back({sum[0] / w, sum[1] / w, sum[2] / w});
    }
    if (pal.empty()) pal.push_back({0, 0, 0});
    for (std::size_t k = 0; k < pal.size(); ++k) {
        std::uint32_t v = 0xff000000u;
        for (int c = 0; c < 3; ++c)
            v |= static_cast<std::uint32_t>(std::clamp(std::lround(pal[k][c]), 0l, 255l)) << (16 - 8 * c);
        q.palette[k] = v;
    }
    // Nearest palette entry per used bin.
    std::vector<std::uint8_t> map(kBins, 0);
    for (int b : bins) {
        double best = 1e300;
        for (std::size_t k = 0; k < pal.size(); ++k) {
            double d = 0;
            for (int c = 0; c < 3; ++c) {
                const double e = chan(b, c) * 8 + 4 - pal[k][c];
                d += e * e;
            }
            if (d < best) best = d, map[static_cast<std::size_t>(b)] = static_cast<std::uint8_t>(k);
        }
    }
    q.index.resize(n);
    for (std::size_t i = 0; i < n; ++i) q.index[i] = map[static_cast<std::size_t>(bin_of(&rgb[i * 3]))];
    return q;
}

}  // namespace

#ifdef FATHOM_HAVE_FFMPEG

namespace {

// The FFmpeg functions the writer calls, by library.
#define FATHOM_FFMPEG_FUNCTIONS(X)              \
    X(avutil, av_frame_alloc)                   \
    X(avutil, av_frame_free)                    \
    X(avutil, av_frame_get_buffer)              \
    X(avutil, av_frame_make_writable)           \
    X(avutil, av_log_set_level)                 \
    X(avutil, av_opt_set)                       \
    X(avutil, av_strerror)                      \
    X(avcodec, av_packet_alloc)                 \
    X(avcodec, av_packet_free)                  \
    X(avcodec, av_packet_rescale_ts)            \
    X(avcodec, avcodec_alloc_context3)          \
    X(avcodec, avcodec_find_encoder)            \
    X(avcodec, avcodec_find_encoder_by_name)    \
    X(avcodec, avcodec_free_context)            \
    X(avcodec, avcodec_open2)                   \
    X(avcodec, avcodec_parameters_from_context) \
    X(avcodec, avcodec_receive_packet)          \
    X(avcodec, avcodec_send_frame)              \
    X(avformat, av_interleaved_write_frame)     \
    X(avformat, av_write_trailer)               \
    X(avformat, avformat_alloc_output_context2) \
    X(avformat, avformat_free_context)          \
    X(avformat, avformat_new_stream)            \
    X(avformat, avformat_write_header)          \
    X(avformat, avio_closep)                    \
    X(avformat, avio_open)                      \
    X(swscale, sws_freeContext)                 \
    X(swscale, sws_getContext)                  \
    X(swscale, sws_scale)

struct Ffmpeg {
#define FATHOM_FFMPEG_POINTER(lib, name) decltype(&::name) name = nullptr;
    FATHOM_FFMPEG_FUNCTIONS(FATHOM_FFMPEG_POINTER)
#undef FATHOM_FFMPEG_POINTER
};

/// The libraries of the FFmpeg whose headers fathom was built with (by their
/// major versions), loaded on first use and kept; throws, naming `subject`,
/// when one cannot be loaded (and tries again on the next call).
const Ffmpeg& ffmpeg(const std::string& subject) {
    static Ffmpeg f;
    static std::once_flag once;
    std::call_once(once, [&] {
        auto soname = [](const char* lib, int major) {
            return "lib" + std::string(lib) + ".so." + std::to_string(major);
        };
        const std::string avutil = soname("avutil", LIBAVUTIL_VERSION_MAJOR),
                          swscale = soname("swscale", LIBSWSCALE_VERSION_MAJOR),
                          avcodec = soname("avcodec", LIBAVCODEC_VERSION_MAJOR),
                          avformat = soname("avformat", LIBAVFORMAT_VERSION_MAJOR);
        struct Lib {
            const std::string& soname;
            void* handle;
        };
        const Lib lib_avutil{avutil, io::load_library(avutil, "FFmpeg", subject)},
            lib_swscale{swscale, io::load_library(swscale, "FFmpeg", subject)},
            lib_avcodec{avcodec, io::load_library(avcodec, "FFmpeg", subject)},
            lib_avformat{avformat, io::load_library(avformat, "FFmpeg", subject)};
        Ffmpeg g;
#define FATHOM_FFMPEG_LOOKUP(lib, name)           \
    g.name = reinterpret_cast<decltype(&::name)>( \
        io::library_function(lib_##lib.handle, #name, lib_##lib.soname, "FFmpeg", subject));
        FATHOM_FFMPEG_FUNCTIONS(FATHOM_FFMPEG_LOOKUP)
#undef FATHOM_FFMPEG_LOOKUP
        f = g;
    });
    return f;
}

}  // namespace

struct VideoWriter::State {
    fs::path path;
    const Ffmpeg& ff;  // loaded before the file is created
    io::AtomicFile file;
    bool gif = false;
    int width = 0, height = 0;  // of the frames given
    AVFormatContext* fmt = nullptr;
    AVCodecContext* enc = nullptr;
    AVStream* stream = nullptr;
    AVFrame* frame = nullptr;
    AVPacket* packet = nullptr;
    SwsContext* sws = nullptr;
    std::int64_t next_pts = 0;
    bool finished = false;

    explicit State(const fs::path& p) : path(p), ff(ffmpeg(p.string())), file(p) {}
    ~State() {
        if (sws) ff.sws_freeContext(sws);
        if (frame) ff.av_frame_free(&frame);
        if (packet) ff.av_packet_free(&packet);
        if (enc) ff.avcodec_free_context(&enc);
        if (fmt) {
            if (fmt->pb) ff.avio_closep(&fmt->pb);
            ff.avformat_free_context(fmt);
        }
    }
    [[noreturn]] void fail(const std::string& what, int err = 0) const {
        std::string reason = what;
        if (err < 0) {
            char buf[AV_ERROR_MAX_STRING_SIZE] = {};
            ff.av_strerror(err, buf, sizeof buf);
            reason += std::string(" (") + buf + ")";
        }
        throw Error(path.string(), reason);
    }
    void drain(bool flush) {
        int rc = ff.avcodec_send_frame(enc, flush ? nullptr : frame);
        if (rc < 0) fail("the encoder refused a frame", rc);
        while ((rc = ff.avcodec_receive_packet(enc, packet)) >= 0) {
            ff.av_packet_rescale_ts(packet, enc->time_base, stream->time_base);
            packet->stream_index = stream->index;
            const int w = ff.av_interleaved_write_frame(fmt, packet);
            if (w < 0) fail("cannot write the video", w);
        }
        if (rc != AVERROR(EAGAIN) && rc != AVERROR_EOF) fail("encoding failed", rc);
    }
};

bool video_supported() {
    return true;
}

VideoWriter::VideoWriter(const fs::path& path, int width, int height, int fps)
    : state_(std::make_unique<State>(path)) {
    State& s = *state_;
    const std::string ext = lower_ext(path);
    if (ext != ".mp4" && ext != ".gif") s.fail("unknown video format '" + ext + "' (expected .mp4 or .gif)");
    if (width < 2 || height < 2) s.fail("a video needs frames of at least 2x2 pixels");
    if (fps < 1 || fps > 240) s.fail("frame rate " + std::to_string(fps) + " is outside 1..240");
    s.ff.av_log_set_level(AV_LOG_ERROR);
    s.gif = ext == ".gif";
    s.width = width;
    s.height = height;
    s.file.close();  // FFmpeg opens the temporary file by name
    const std::string tmp = s.file.temp_path().string();
    int rc = s.ff.avformat_alloc_output_context2(&s.fmt, nullptr, s.gif ? "gif" : "mp4", tmp.c_str());
    if (rc < 0 || !s.fmt) s.fail("cannot set up the " + ext.substr(1) + " container", rc);
    const AVCodec* codec = nullptr;
    if (s.gif) {
        codec = s.ff.avcodec_find_encoder(AV_CODEC_ID_GIF);
    } else {
        codec = s.ff.avcodec_find_encoder_by_name("libx264");
        if (!codec) codec = s.ff.avcodec_find_encoder(AV_CODEC_ID_MPEG4);
    }
    if (!codec) s.fail("this FFmpeg has no " + std::string(s.gif ? "GIF" : "H.264 or MPEG-4") + " encoder");
    s.stream = s.ff.avformat_new_stream(s.fmt, nullptr);
    s.enc = s.ff.avcodec_alloc_context3(codec);
    s.frame = s.ff.av_frame_alloc();
    s.packet = s.ff.av_packet_alloc();
    if (!s.stream || !s.enc || !s.frame || !s.packet) s.fail("out of memory");
    // yuv420p halves chroma: MP4 frames need even sizes.
    s.enc->width = s.gif ? width : width & ~1;
    s.enc->height = s.gif ? height : height & ~1;
    s.enc->time_base = AVRational{1, fps};
    s.enc->framerate = AVRational{fps, 1};
    s.enc->pix_fmt = s.gif ? AV_PIX_FMT_PAL8 : AV_PIX_FMT_YUV420P;
    s.enc->gop_size = 2 * fps;
    if (!s.gif) {
        s.enc->bit_rate = 0;
        if (std::string(codec->name) == "libx264") {
            s.ff.av_opt_set(s.enc->priv_data, "crf", "18", 0);
            s.ff.av_opt_set(s.enc->priv_data, "preset", "medium", 0);
        } else {
            s.enc->bit_rate = static_cast<std::int64_t>(width) * height * fps / 4;
        }
    }
    if (s.fmt->oformat->flags & AVFMT_GLOBALHEADER) s.enc->flags |= AV_CODEC_FLAG_GLOBAL_HEADER;
    rc = s.ff.avcodec_open2(s.enc, codec, nullptr);
    if (rc < 0) s.fail(std::string("cannot open the ") + codec->name + " encoder", rc);
    rc = s.ff.avcodec_parameters_from_context(s.stream->codecpar, s.enc);
    if (rc < 0) s.fail("cannot set the stream parameters", rc);
    s.stream->time_base = s.enc->time_base;
    if (s.gif) s.ff.av_opt_set(s.fmt->priv_data, "loop", "0", 0);  // loop forever
    rc = s.ff.avio_open(&s.fmt->pb, tmp.c_str(), AVIO_FLAG_WRITE);
    if (rc < 0) s.fail("cannot open the file for writing", rc);
    rc = s.ff.avformat_write_header(s.fmt, nullptr);
    if (rc < 0) s.fail("cannot write the header", rc);
    s.frame->format = s.enc->pix_fmt;
    s.frame->width = s.enc->width;
    s.frame->height = s.enc->height;
    rc = s.ff.av_frame_get_buffer(s.frame, 0);
    if (rc < 0) s.fail("out of memory", rc);
    if (!s.gif) {
        s.sws = s.ff.sws_getContext(width, height, AV_PIX_FMT_RGB24, s.enc->width, s.enc->height,
                                    AV_PIX_FMT_YUV420P, SWS_BICUBIC, nullptr, nullptr, nullptr);
        if (!s.sws) s.fail("cannot set up the color conversion");
    }
}

VideoWriter::~VideoWriter() = default;

void VideoWriter::add(const Image& image) {
    State& s = *state_;
    if (s.finished) s.fail("frames added after finish()");
    if (image.width != s.width || image.height != s.height)
        s.fail("frame of " + std::to_string(image.width) + "x" + std::to_string(image.height) + " in a " +
               std::to_string(s.width) + "x" + std::to_string(s.height) + " video");
    int rc = s.ff.av_frame_make_writable(s.frame);
    if (rc < 0) s.fail("out of memory", rc);
    const std::vector<std::uint8_t> rgb = rgb8(image);
    if (s.gif) {
        const Quantized q = quantize(rgb);
        for (int y = 0; y < s.height; ++y)
            std::copy_n(q.index.data() + static_cast<std::size_t>(y) * static_cast<std::size_t>(s.width),
                        s.width, s.frame->data[0] + static_cast<std::ptrdiff_t>(y) * s.frame->linesize[0]);
        std::copy(q.palette.begin(), q.palette.end(), reinterpret_cast<std::uint32_t*>(s.frame->data[1]));
    } else {
        const std::uint8_t* src[1] = {rgb.data()};
        const int stride[1] = {3 * s.width};
        s.ff.sws_scale(s.sws, src, stride, 0, s.height, s.frame->data, s.frame->linesize);
    }
    s.frame->pts = s.next_pts++;
    s.drain(false);
}

void VideoWriter::finish() {
    State& s = *state_;
    if (s.finished) return;
    if (s.next_pts == 0) s.fail("a video needs at least one frame");
    s.drain(true);
    const int rc = s.ff.av_write_trailer(s.fmt);
    if (rc < 0) s.fail("cannot write the trailer", rc);
    s.ff.avio_closep(&s.fmt->pb);
    s.finished = true;
    s.file.commit();
}

#else  // no FFmpeg

struct VideoWriter::State {};

bool video_supported() {
    return false;
}

VideoWriter::VideoWriter(const fs::path& path, int, int, int) {
    (void)&quantize;
    (void)&rgb8;
    (void)&lower_ext;
    throw Error(path.string(),
                "this fathom was built without FFmpeg's libraries (libavformat-dev, "
                "libavcodec-dev, libswscale-dev): videos cannot be written");
}
VideoWriter::~VideoWriter() = default;
void VideoWriter::add(const Image&) {}
void VideoWriter::finish() {}

#endif

}  // namespace fathom
