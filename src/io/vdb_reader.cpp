// OpenVDB reader (.vdb) through libopenvdb (Debian's libopenvdb-dev, OpenVDB 10),
// in fathom's OpenVDB module (modules/vdb/vdb_module.cpp, fathom-vdb.so), which
// this file loads (dlopen) on the first .vdb read and runs in a child process.
//
// A VDB file holds named sparse grids. fathom reads one float (or double,
// converted to float32) grid as a dense float32 volume over the grid's active
// voxel bounding box: node (i, j, k) of the volume is the VDB voxel
// bbox.min + (i, j, k), with the value the grid's accessor gives there (the
// stored value: active voxels, inactive voxels, tiles; the background outside
// allocated nodes). An axis of the box one voxel thick is extended by one
// voxel (the next, inactive voxel, normally the background value) because
// fathom needs two samples per axis.
//
// Placement: VDB has no patient space; its world coordinates are taken as
// fathom's world coordinates unchanged (SPEC §2). The grid's index-to-world
// transform must be linear (scale, translation, rotation, general affine):
// origin = indexToWorld(bbox.min), column a of M = indexToWorld(bbox.min +
// e_a) − origin. Frustum (non-linear) transforms are refused.
//
// Truncated and corrupt files: OpenVDB does not check its reads (a
// truncated file reads as a partial or empty grid, silently, and a corrupt
// count loops on past the end of the file). So fathom first walks the file
// header, the file metadata, the chain of grid descriptors and each grid's
// metadata itself, with bounds checks, and refuses a file whose grids end
// past its last byte; then it reads the grids through OpenVDB's io::Archive
// (the base of io::File and io::Stream) from a std::ifstream that throws on
// any short read. There is no delayed loading: that memory-maps the file,
// and touching a mapped page past the end of a truncated file would fault
// instead of failing a read. Every exception OpenVDB throws
// (openvdb::Exception, std::exception) becomes fathom::Error(path, reason).
// Isolation: OpenVDB 10.0 trusts the chunk sizes inside a grid's compressed
// data (io::bloscFromStream copies a stored "uncompressed" chunk into its
// buffer before comparing the chunk's size with the buffer's, a heap
// overflow on a damaged file), and fathom cannot check those chunks without
// re-implementing the tree format. So everything OpenVDB does runs in a
// child process (fork): it reads the grid and sends the result back through a
// pipe (the dense volume slab by slab, or the grid list, or the error, and
// the warnings on the way); whatever a damaged file does to the child's heap
// cannot reach the caller's. A child that dies (a signal, an abort, a
// sanitizer's report) becomes an Error naming the file. The parent checks
// every size the child sends before allocating. In the child TBB runs on one
// thread (fork copies only the calling thread). When a read fails inside a
// tree's topology, OpenVDB's RootNode::readTopology leaks the node it was
// reading; in the child that no longer matters.
//
// Listing uses the grid statistics OpenVDB writes beside each grid
// (file_voxel_count, file_bbox_min, file_bbox_max) and reads the grid itself
#include <fcntl.h>
#include <sys/wait.h>
#include <unistd.h>

#include <array>
#include <cerrno>
#include <csignal>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"

#include "io/io_util.h"
#include "io/shared_library.h"
#include "io/vdb_protocol.h"

#ifndef FATHOM_VDB_MODULE_BUILD
#define FATHOM_VDB_MODULE_BUILD ""
#endif
#ifndef FATHOM_VDB_MODULE_INSTALL
#define FATHOM_VDB_MODULE_INSTALL ""
#endif

namespace fathom {
namespace {

using namespace vdb;

/// The module's entry point, the module loaded on first use.
ChildFn* module_entry(const std::string& subject) {
    static ChildFn* const entry = [&] {
        const std::string path = io::find_module(kModuleName, "FATHOM_VDB_MODULE",
                                                 {FATHOM_VDB_MODULE_BUILD, FATHOM_VDB_MODULE_INSTALL},
                                                 "read VDB files", "OpenVDB module", subject)
                                     .string();
        void* handle = io::load_library(path, "fathom", subject);
        return reinterpret_cast<ChildFn*>(
            io::library_function(handle, kChildFunction, path, "fathom", subject));
    }();
    return entry;
}

/// The parent's end of the pipe: every read is checked, and the end of the stream (the child
/// gone) is an error naming the file.
class Receiver {
public:
    Receiver(int fd, std::function<void()> on_end) : fd_(fd), on_end_(std::move(on_end)) {}
    void bytes(void* p, std::size_t n) {
        auto* c = static_cast<char*>(p);
        while (n > 0) {
            const ssize_t r = ::read(fd_, c, n);
            if (r < 0 && errno == EINTR) continue;
            if (r <= 0) on_end_();  // throws
            c += r;
            n -= static_cast<std::size_t>(r);
        }
    }
    template <class T>
    T pod() {
        T v{};
        bytes(&v, sizeof v);
        return v;
    }
    std::string str(const std::string& subject) {
        const auto n = pod<std::uint64_t>();
        if (n > (std::uint64_t{1} << 20))
            throw Error(subject, "the OpenVDB reading process sent a malformed reply");
        std::string s(n, '\0');
        bytes(s.data(), s.size());
        return s;
    }

private:
    int fd_;
    std::function<void()> on_end_;
};

/// Runs the module's `op` on the file in a child process, which sends its result through the pipe;
/// the parent receives it with `receive`, which returns after reading the result record. Warnings are passed
/// on to fathom::warn, an error record becomes Error(subject, reason), a child that ends without a
/// result (killed by a signal, aborted) an Error that says so.
template <class Result>
Result in_child(const std::string& subject, const std::filesystem::path& path, Op op, const std::string& grid,
                const std::function<Result(Tag, Receiver&)>& receive) {
    const std::uint64_t size = io::file_size_checked(subject, path, "file");
    if (size == 0) throw Error(subject, "the file is empty");
    ChildFn* const child = module_entry(subject);  // loaded here: the child only runs it
    const std::string path_text = path.string();
    int fds[2];
    if (::pipe(fds) != 0)
        throw Error(subject,
                    std::string("cannot create a pipe for the OpenVDB reader: ") + std::strerror(errno));
    const pid_t pid = ::fork();
    if (pid < 0) {
        const int e = errno;
        ::close(fds[0]);
        ::close(fds[1]);
        throw Error(subject, std::string("cannot start the OpenVDB reading process: ") + std::strerror(e));
    }
    if (pid == 0) {  // the child: OpenVDB reads here, then the process ends without unwinding
        ::close(fds[0]);
        // The file's damage may make the C library or a sanitizer print a report before the
        // child dies; the parent says what happened, in one line.
        if (const int null = ::open("/dev/null", O_WRONLY); null >= 0) ::dup2(null, STDERR_FILENO);
        child(fds[1], static_cast<int>(op), subject.c_str(), path_text.c_str(), size, grid.c_str());
        ::_exit(0);
    }

    ::close(fds[1]);
    struct Reap {  // closes the pipe and reaps the child on every path out
        pid_t pid;
        int fd;
        bool waited = false;
        int wait() {
            int status = 0;
            while (::waitpid(pid, &status, 0) < 0 && errno == EINTR) {
            }
            waited = true;
            return status;
        }
        ~Reap() {
            ::close(fd);
            if (!waited) {
                ::kill(pid, SIGKILL);
                wait();
            }
        }
    } reap{pid, fds[0]};
    Receiver in(fds[0], [&] {
        const int status = reap.wait();
        std::string how;
        if (WIFSIGNALED(status))
            how = "was killed by signal " + std::to_string(WTERMSIG(status)) + " (" +
                  std::string(strsignal(WTERMSIG(status))) + ")";
        else
            how = "ended with status " + std::to_string(WEXITSTATUS(status));
        throw Error(subject, "OpenVDB failed reading the file: its reading process " + how +
                                 " without a result (a corrupt file)");
    });
    for (;;) {
        const auto tag = in.pod<Tag>();
        if (tag == Tag::warning) {
            warn(in.str(subject));
        } else if (tag == Tag::error) {
            const std::string reason = in.str(subject);
            throw Error(subject, reason);
        } else {
            Result r = receive(tag, in);
            reap.wait();
            return r;
        }
    }
}

// ================================================================ volumes

/// In the parent: the volume record the child sent, checked before anything is allocated.
Volume receive_volume(const std::string& subject, Receiver& in) {
    std::array<std::int64_t, 3> dims{};
    for (auto& d : dims) d = in.pod<std::int64_t>();
    for (const auto d : dims)
        if (d < 2) throw Error(subject, "the OpenVDB reading process sent a malformed reply");
    io::grid_bytes(subject, "active bounding box", io::GridShape{dims, DType::f32, 1});
    Vec3 origin;
    origin.x = in.pod<double>();
    origin.y = in.pod<double>();
    origin.z = in.pod<double>();
    std::array<Vec3, 3> cols;
    for (auto& c : cols) {
        c.x = in.pod<double>();
        c.y = in.pod<double>();
        c.z = in.pod<double>();
    }
    Volume v(dims, DType::f32);
    in.bytes(v.data<float>(), static_cast<std::size_t>(dims[0] * dims[1] * dims[2]) * sizeof(float));
    v.set_origin(origin);
    v.set_axes(Mat3::from_columns(cols[0], cols[1], cols[2]), subject);
    return v;
}

}  // namespace

std::vector<VdbGrid> list_vdb_grids(const std::filesystem::path& path) {
    const std::string subject = path.string();
    return in_child<std::vector<VdbGrid>>(subject, path, Op::list, "", [&](Tag tag, Receiver& in) {
        if (tag != Tag::list) throw Error(subject, "the OpenVDB reading process sent a malformed reply");
        const auto n = in.pod<std::uint64_t>();
        std::vector<VdbGrid> grids;
        for (std::uint64_t i = 0; i < n; ++i) {
            VdbGrid g;
            g.name = in.str(subject);
            g.type = in.str(subject);
            g.active_voxels = in.pod<std::uint64_t>();
            g.bbox_min = in.pod<std::array<std::int64_t, 3>>();
            g.bbox_max = in.pod<std::array<std::int64_t, 3>>();
            grids.push_back(std::move(g));
        }
        return grids;
    });
}

Volume read_vdb(const std::filesystem::path& path, const std::string& grid) {
    const std::string subject = path.string();
    Volume v = in_child<Volume>(subject, path, Op::read, grid, [&](Tag tag, Receiver& in) {
        if (tag != Tag::volume) throw Error(subject, "the OpenVDB reading process sent a malformed reply");
        return receive_volume(subject, in);
    });
    io::check_finite(subject, v);
    return v;
}

}  // namespace fathom
