// AtomicFile: writes a file under a temporary name beside its target and
// renames it over the target on commit(), so that a failure never leaves a
// partial file (SPEC §6). Without commit() the destructor removes the
// temporary file. Errors throw fathom::Error(target, reason).
#pragma once

#include <cstddef>
#include <filesystem>
#include <string>

namespace fathom::io {

class AtomicFile {
public:
    /// Creates and opens ".<name>.tmp-<pid>-<counter>" in the target's directory.
    explicit AtomicFile(std::filesystem::path target);
    ~AtomicFile();
    AtomicFile(const AtomicFile&) = delete;
    AtomicFile& operator=(const AtomicFile&) = delete;

    /// Appends bytes to the temporary file.
    void write(const void* data, std::size_t size);
    /// Flushes and closes the temporary file but keeps it, for writers that
    /// open the file by name themselves (OpenEXR); then write to temp_path().
    void close();
    /// Closes (if still open) and renames the temporary file over the target.
    void commit();

    [[nodiscard]] const std::filesystem::path& target() const noexcept { return target_; }
    [[nodiscard]] const std::filesystem::path& temp_path() const noexcept { return temp_; }

private:
    [[noreturn]] void fail(const std::string& what, int err) const;

    std::filesystem::path target_;
    std::filesystem::path temp_;
    int fd_ = -1;
    bool committed_ = false;
};

}  // namespace fathom::io
