// Video files of rendered frames (turntables): MP4 (H.264) or animated GIF,
// through FFmpeg's libraries when fathom was built with them
// (docs/formats.md, "Video").
#pragma once

#include <filesystem>
#include <memory>

#include "fathom/image.h"

namespace fathom {

/// True when this build can write videos (FFmpeg's libavformat, libavcodec
/// and libswscale were found at build time).
bool video_supported();

/// Streams frames into a video file chosen by extension: .mp4 (H.264 with
/// libx264, else MPEG-4 part 2; yuv420p, so an odd width or height is
/// rounded down to even) or .gif (a palette of 256 colors per frame by median
/// cut, looping). Colors are converted to sRGB 8-bit as for PNG; alpha is
/// dropped (composite over the background first). Written to a temporary
/// name and renamed by finish(), so a failure leaves no partial file.
/// Errors throw fathom::Error(path, reason).
class VideoWriter {
public:
    VideoWriter(const std::filesystem::path& path, int width, int height, int fps);
    ~VideoWriter();
    VideoWriter(const VideoWriter&) = delete;
    VideoWriter& operator=(const VideoWriter&) = delete;

    /// Appends a frame of the size given at construction.
    void add(const Image& frame);
    /// Flushes the encoder, writes the trailer and renames the file into place.
    void finish();

    struct State;

private:
    std::unique_ptr<State> state_;
};

}  // namespace fathom
