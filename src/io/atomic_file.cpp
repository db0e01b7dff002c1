#include "io/atomic_file.h"

#include <fcntl.h>
#include <unistd.h>

#include <atomic>
#include <cerrno>
#include <cstring>
#include <string>
#include <system_error>
#include <utility>

#include "fathom/error.h"
#include "fathom/io.h"

namespace fathom::io {
namespace {

std::atomic<unsigned> g_counter{0};

std::filesystem::path temp_name(const std::filesystem::path& target) {
    std::string name = ".";
    name += target.filename().string();
    name += ".tmp-";  // appended piece by piece: "lit" + std::string&& trips GCC 12's -Wrestrict at -O3
    name += std::to_string(::getpid());
    name += '-';
    name += std::to_string(g_counter.fetch_add(1, std::memory_order_relaxed));
    return target.parent_path() / name;
}

}  // namespace

AtomicFile::AtomicFile(std::filesystem::path target) : target_(std::move(target)) {
    if (target_.filename().empty()) throw Error(target_.string(), "not a file name");
    // O_EXCL: never reuse (and later remove) a file that someone else made.
    for (int attempt = 0; attempt < 100 && fd_ < 0; ++attempt) {
        temp_ = temp_name(target_);
        fd_ = ::open(temp_.c_str(), O_WRONLY | O_CREAT | O_EXCL | O_CLOEXEC, 0666);
        if (fd_ < 0 && errno != EEXIST)
            fail("cannot create temporary file '" + temp_.filename().string() + "'", errno);
    }
    if (fd_ < 0) fail("cannot create a temporary file", EEXIST);
}

AtomicFile::~AtomicFile() {
    if (fd_ >= 0) ::close(fd_);
    if (!committed_ && !temp_.empty()) {
        std::error_code ec;
        std::filesystem::remove(temp_, ec);
    }
}

void AtomicFile::fail(const std::string& what, int err) const {
    throw Error(target_.string(), what + ": " + std::strerror(err));
}

void AtomicFile::write(const void* data, std::size_t size) {
    if (fd_ < 0) throw Error(target_.string(), "write after close");
    const auto* p = static_cast<const char*>(data);
    while (size > 0) {
        const ssize_t n = ::write(fd_, p, size);
        if (n < 0 && errno == EINTR) continue;
        if (n < 0) fail("write failed", errno);
        p += n;
        size -= static_cast<std::size_t>(n);
    }
}

void AtomicFile::close() {
    if (fd_ < 0) return;
    const int fd = std::exchange(fd_, -1);
    const bool synced = ::fsync(fd) == 0 || errno == EINVAL;  // EINVAL: the file system cannot sync
    const int sync_err = errno;
    if (::close(fd) != 0) fail("close failed", errno);
    if (!synced) fail("fsync failed", sync_err);
}

void AtomicFile::commit() {
    if (committed_) return;
    close();
    if (::rename(temp_.c_str(), target_.c_str()) != 0)
        fail("cannot rename the temporary file into place", errno);
    committed_ = true;
}

}  // namespace fathom::io

namespace fathom {

void write_text_file(const std::filesystem::path& path, const std::string& text) {
    io::AtomicFile file(path);
    file.write(text.data(), text.size());
    file.commit();
}

}  // namespace fathom
