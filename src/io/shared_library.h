// Shared libraries loaded at run time (dlopen) for optional dependencies that
// only some commands need, so that other processes neither map nor relocate
// them (src/io/video_writer.cpp: FFmpeg). Failures are fathom::Error(subject,
// reason) naming the library.
#pragma once

#include <string>

namespace fathom::io {

/// dlopen(soname) now and locally; the handle is never closed. Throws
/// Error(subject, "cannot load <what>'s <soname>: <why>").
void* load_library(const std::string& soname, const std::string& what, const std::string& subject);

/// The function `name` in a loaded library. Throws Error(subject, "<what>'s
/// <soname> has no function <name> ...") where it is missing.
void* library_function(void* handle, const char* name, const std::string& soname, const std::string& what,
                       const std::string& subject);

}  // namespace fathom::io
