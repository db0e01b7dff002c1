// The pipe between fathom's OpenVDB reader (src/io/vdb_reader.cpp, in the
// caller's process) and its OpenVDB module (modules/vdb/vdb_module.cpp,
// loaded with dlopen and run in a child process): records and the module's
// entry point.
#pragma once

#include <unistd.h>

#include <cerrno>
#include <cstddef>
#include <cstdint>
#include <string>

namespace fathom::vdb {

/// What the child sends, record by record: a tag byte, then the record.
enum class Tag : char { warning = 'W', error = 'E', volume = 'V', list = 'L' };

/// The child's end of the pipe.
class Sender {
public:
    explicit Sender(int fd) : fd_(fd) {}
    /// Writes all n bytes; when the parent has gone, the child just ends.
    void bytes(const void* p, std::size_t n) {
        const auto* c = static_cast<const char*>(p);
        while (n > 0) {
            const ssize_t w = ::write(fd_, c, n);
            if (w < 0 && errno == EINTR) continue;
            if (w <= 0) ::_exit(3);
            c += w;
            n -= static_cast<std::size_t>(w);
        }
    }
    template <class T>
    void pod(const T& v) {
        bytes(&v, sizeof v);
    }
    void str(const std::string& s) {
        pod(static_cast<std::uint64_t>(s.size()));
        bytes(s.data(), s.size());
    }
    void tag(Tag t) { pod(t); }

private:
    int fd_;
};

/// What the child is asked to do.
enum class Op : int { list = 1, read = 2 };

/// The module's entry point, run in the child: checks the file (`size`
/// bytes) and does `op` on it (`grid`: the grid to read), sending warnings,
/// then the result or an error, through `fd`; returns when done.
using ChildFn = void(int fd, int op, const char* subject, const char* path, std::uint64_t size,
                     const char* grid);
inline constexpr const char* kChildFunction = "fathom_vdb_child";
/// The module's file name.
inline constexpr const char* kModuleName = "fathom-vdb.so";

}  // namespace fathom::vdb
