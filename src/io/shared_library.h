// Shared libraries loaded at run time (dlopen) for optional dependencies that
// only some commands need, so that other processes neither map nor relocate
// them (src/io/video_writer.cpp: FFmpeg). Failures are fathom::Error(subject,
// reason) naming the library.
#pragma once

#include <filesystem>
#include <string>
#include <vector>

namespace fathom::io {

/// dlopen(soname) now and locally; the handle is never closed. Throws
/// Error(subject, "cannot load <what>'s <soname>: <why>").
void* load_library(const std::string& soname, const std::string& what, const std::string& subject);

/// The function `name` in a loaded library. Throws Error(subject, "<what>'s
/// <soname> has no function <name> ...") where it is missing.
void* library_function(void* handle, const char* name, const std::string& soname, const std::string& what,
                       const std::string& subject);

/// Where one of fathom's own modules (fathom-vdb.so, fathom-dicom.so) is:
/// $env when set (then only there); else beside the binary that holds this
/// code (the fathom executable, the Python extension), in ../lib/fathom from
/// it (an installed executable), then at each of `known` (where this build
/// put it, where `cmake --install` puts it; empty entries are skipped).
/// Throws Error(subject, "cannot <purpose>: fathom's <what> <...> does not
/// exist / is not installed (looked for ...)").
std::filesystem::path find_module(const std::string& name, const char* env,
                                  const std::vector<std::string>& known, const std::string& purpose,
                                  const std::string& what, const std::string& subject);

}  // namespace fathom::io
