// fathom's OpenVDB module (fathom-vdb.so): everything that calls libopenvdb,
// loaded at run time only by processes that read a .vdb file
// (src/io/vdb_reader.cpp) and run in the child process that reader starts.
// OpenVDB and what it brings (TBB, Blosc, Boost, log4cplus) hold most of
// the symbols a fathom process would otherwise bind at start-up, and about
// 27 MB: other processes never map them. The file checks and the reading
// are described at the top of src/io/vdb_reader.cpp.
#include <openvdb/Exceptions.h>
#include <openvdb/io/Archive.h>
#include <openvdb/io/GridDescriptor.h>
#include <openvdb/io/io.h>
#include <openvdb/openvdb.h>
#include <openvdb/tools/Dense.h>
#include <tbb/global_control.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <limits>
#include <memory>
#include <new>
#include <optional>
#include <string>
#include <type_traits>
#include <vector>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"

#include "io/vdb_protocol.h"

namespace fathom::vdb {
namespace {

/// openvdb::initialize() once per process (registers the grid and map types).
void init_openvdb() {
    static const bool done = [] {
        openvdb::initialize();
        return true;
    }();
    (void)done;
}

/// Runs f, turning OpenVDB's and the standard library's exceptions into Error(subject, ...).
template <class F>
auto guarded(const std::string& subject, F&& f) -> decltype(f()) {
    try {
        return f();
    } catch (const Error&) {
        throw;
    } catch (const openvdb::Exception& e) {
        throw Error(subject, std::string("OpenVDB cannot read the file (") + e.what() +
                                 "); not a VDB file, or a corrupt or truncated one");
    } catch (const std::ios_base::failure&) {
        throw Error(subject, "truncated or corrupt: a read went past the end of the file or failed");
    } catch (const std::bad_alloc&) {
        throw Error(subject, "OpenVDB ran out of memory reading the file (corrupt or truncated file?)");
    } catch (const std::exception& e) {
        throw Error(subject, std::string("OpenVDB cannot read the file (") + e.what() +
                                 "); not a VDB file, or a corrupt or truncated one");
    }
}

std::string coord_text(const openvdb::Coord& c) {
    return "(" + std::to_string(c.x()) + ", " + std::to_string(c.y()) + ", " + std::to_string(c.z()) + ")";
}

/// Active voxel count and bbox from the statistics metadata written with the grid; nullopt when
/// they are missing or inconsistent.
std::optional<VdbGrid> stats_from_metadata(const openvdb::GridBase& grid) {
    using openvdb::GridBase;
    const auto count = grid.getMetadata<openvdb::Int64Metadata>(GridBase::META_FILE_VOXEL_COUNT);
    const auto lo = grid.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MIN);
    const auto hi = grid.getMetadata<openvdb::Vec3IMetadata>(GridBase::META_FILE_BBOX_MAX);
    if (!count || !lo || !hi || count->value() < 0) return std::nullopt;
    VdbGrid g;
    g.active_voxels = static_cast<std::uint64_t>(count->value());
    if (g.active_voxels == 0) return g;  // bbox stays (0, 0, 0)
    std::uint64_t box_voxels = 1;
    for (int a = 0; a < 3; ++a) {
        if (lo->value()[a] > hi->value()[a]) return std::nullopt;
        g.bbox_min[a] = lo->value()[a];
        g.bbox_max[a] = hi->value()[a];
        const auto extent = static_cast<std::uint64_t>(g.bbox_max[a] - g.bbox_min[a] + 1);
        box_voxels = box_voxels > UINT64_MAX / extent ? UINT64_MAX : box_voxels * extent;
    }
    if (g.active_voxels > box_voxels) return std::nullopt;
    return g;
}

VdbGrid stats_from_grid(const openvdb::GridBase& grid) {
    VdbGrid g;
    g.active_voxels = grid.activeVoxelCount();
    if (g.active_voxels == 0) return g;
    const openvdb::CoordBBox box = grid.evalActiveVoxelBoundingBox();
    for (int a = 0; a < 3; ++a) {
        g.bbox_min[a] = box.min()[a];
        g.bbox_max[a] = box.max()[a];
    }
    return g;
}

// ================================================================ structure check

/// Bounds-checked little-endian reads of the file's header and grid descriptors.
class Cursor {
public:
    Cursor(const std::string& subject, const std::filesystem::path& path, std::uint64_t size)
        : subject_(subject), in_(path, std::ios::binary), size_(size), limit_(size) {
        if (!in_) throw Error(subject_, "cannot open the file");
    }
    [[nodiscard]] std::uint64_t pos() const { return pos_; }
    /// Reads past `limit` (at most the file size) are errors; `region` names what it bounds.
    void set_limit(std::uint64_t limit, std::string region) {
        limit_ = std::min(limit, size_);
        region_ = std::move(region);
    }

    /// Error unless n more bytes from the current position lie within the limit.
    void need(std::uint64_t n, const std::string& what) const {
        if (n <= limit_ - pos_) return;
        if (region_.empty())
            throw Error(subject_, "truncated: the file has " + std::to_string(size_) + " bytes, but " + what +
                                      " needs bytes up to " + std::to_string(pos_ + n) +
                                      " (an incomplete copy?)");
        throw Error(subject_, "corrupt file: " + what + " runs past the end of " + region_ + " (byte " +
                                  std::to_string(limit_) + ")");
    }
    void read(void* dst, std::size_t n, const std::string& what) {
        need(n, what);
        in_.read(static_cast<char*>(dst), static_cast<std::streamsize>(n));
        if (static_cast<std::size_t>(in_.gcount()) != n) throw Error(subject_, "read error in " + what);
        pos_ += n;
    }
    template <class T>
    T pod(const std::string& what) {
        T v{};
        read(&v, sizeof v, what);
        return v;
    }
    /// A string as OpenVDB writes it: uint32 length, then the bytes.
    std::string str(const std::string& what) {
        const auto n = pod<std::uint32_t>(what);
        need(n, what);
        std::string s(n, '\0');
        if (n > 0) read(s.data(), n, what);
        return s;
    }
    void skip_str(const std::string& what) { skip(pod<std::uint32_t>(what), what); }
    void skip(std::uint64_t n, const std::string& what) {
        need(n, what);
        seek(pos_ + n);
    }
    void seek(std::uint64_t p) {
        pos_ = p;
        in_.seekg(static_cast<std::streamoff>(p));
        if (!in_) throw Error(subject_, "cannot seek to byte " + std::to_string(p));
    }
    /// A metadata map (MetaMap::readMeta): a count, then name, type name, size and value bytes.
    void skip_metadata(const std::string& what) {
        const auto count = pod<std::uint32_t>(what);
        for (std::uint32_t i = 0; i < count; ++i) {
            const std::string item = what + " item " + std::to_string(i);
            skip_str(item);  // name
            skip_str(item);  // type name
            skip(pod<std::uint32_t>(item), item);
        }
    }

private:
    const std::string& subject_;
    std::ifstream in_;
    std::uint64_t size_;
    std::uint64_t limit_;
    std::string region_;
    std::uint64_t pos_ = 0;
};

/// Walks the file as OpenVDB's io::File reads it (Archive::readHeader, MetaMap::readMeta,
/// GridDescriptor::read, then each grid's compression flags and metadata), checking that every
/// part lies inside the file and each grid's metadata inside the grid: a truncated file gets an
/// error that says so, and no garbage length reaches OpenVDB's allocations. Returns whether the
/// file holds grid offsets (io::File output does; io::Stream output does not, and is then checked
/// only up to the file metadata).
bool check_structure(const std::string& subject, const std::filesystem::path& path, std::uint64_t size) {
    Cursor c(subject, path, size);
    if (size < 8 || c.pod<std::int64_t>("the magic number") != openvdb::OPENVDB_MAGIC)
        throw Error(subject, "not an OpenVDB file (it does not start with the VDB magic number)");
    auto version = c.pod<std::uint32_t>("the file header");
    if (version < 211) {  // separate major, minor and patch numbers
        const auto minor = c.pod<std::uint32_t>("the file header");
        const auto patch = c.pod<std::uint32_t>("the file header");
        version = 100 * version + 10 * minor + patch;
    } else {
        c.skip(8, "the file header");  // library major and minor version
    }
    bool offsets = true;
    if (version >= 212) offsets = c.pod<char>("the file header") != 0;
    if (version >= 220 && version < 222) c.skip(1, "the file header");  // compression flag
    c.skip(version >= openvdb::OPENVDB_FILE_VERSION_BOOST_UUID ? 36 : 16, "the file header");  // UUID
    c.skip_metadata("the file metadata");
    if (!offsets) return false;

    const auto grid_count = c.pod<std::int32_t>("the grid count");
    if (grid_count < 0)
        throw Error(subject, "corrupt file: negative grid count " + std::to_string(grid_count));
    for (std::int32_t i = 0; i < grid_count; ++i) {
        const std::string what = "the descriptor of grid " + std::to_string(i);
        // The unique name: NAME, or NAME + separator + n for the n-th duplicate.
        const std::string name = openvdb::io::GridDescriptor::stripSuffix(c.str(what));
        c.skip_str(what);  // grid type
        const bool instance =
            version >= openvdb::OPENVDB_FILE_VERSION_GRID_INSTANCING && !c.str(what).empty();  // parent
        const auto grid_pos = c.pod<std::int64_t>(what);
        const auto block_pos = c.pod<std::int64_t>(what);
        const auto end_pos = c.pod<std::int64_t>(what);
        const auto here = static_cast<std::int64_t>(c.pos());
        // An instance (a grid sharing another's tree) has no blocks: its block offset is 0.
        if (grid_pos < here || end_pos < grid_pos ||
            (!instance && (block_pos < grid_pos || end_pos < block_pos)))
            throw Error(subject, "corrupt file: grid '" + name + "' has inconsistent offsets " +
                                     std::to_string(grid_pos) + ", " + std::to_string(block_pos) + ", " +
                                     std::to_string(end_pos));
        if (static_cast<std::uint64_t>(end_pos) > size)
            throw Error(subject, "truncated: the file has " + std::to_string(size) + " bytes, but grid '" +
                                     name + "' ends at byte " + std::to_string(end_pos) +
                                     " (an incomplete copy?)");
        // The grid's compression flags and metadata lie before its topology and blocks.
        c.seek(static_cast<std::uint64_t>(grid_pos));
        c.set_limit(static_cast<std::uint64_t>(instance ? end_pos : block_pos), "grid '" + name + "'");
        if (version >= openvdb::OPENVDB_FILE_VERSION_NODE_MASK_COMPRESSION)
            c.skip(4, "the compression flags of grid '" + name + "'");
        c.skip_metadata("the metadata of grid '" + name + "'");
        c.set_limit(size, {});
        c.seek(static_cast<std::uint64_t>(end_pos));
    }
    return true;
}

// ================================================================ grids

/// The grids of a VDB file, read through OpenVDB's Archive (what io::File and io::Stream are
/// built on) from a std::ifstream that throws on a short or failed read: OpenVDB does not check
/// its reads, and a corrupt count would otherwise loop on past the end of the file building a
/// tree of garbage. Files with grid offsets are read one grid at a time; without, all at once.
/// No delayed loading (no memory map: see the top of the file).
class VdbArchive final : public openvdb::io::Archive {
public:
    VdbArchive(const std::string& subject, const std::filesystem::path& path)
        : subject_(subject), in_(path, std::ios::binary) {
        if (!in_) throw Error(subject, "cannot open the file");
        in_.exceptions(std::ios::failbit | std::ios::badbit);
        readHeader(in_);
        stream_meta_ = std::make_shared<openvdb::io::StreamMetadata>();
        stream_meta_->setSeekable(inputHasGridOffsets());
        openvdb::io::setStreamMetadataPtr(in_, stream_meta_, /*transfer=*/false);
        setFormatVersion(in_);
        setLibraryVersion(in_);
        setDataCompression(in_);
        openvdb::MetaMap file_meta;
        file_meta.readMeta(in_);
        const std::int32_t count = readGridCount(in_);
        Archive::NamedGridMap named;
        for (std::int32_t i = 0; i < count; ++i) {
            Entry e;
            e.gd.read(in_);
            if (inputHasGridOffsets()) {
                e.gd.seekToEnd(in_);
            } else {
                e.grid = create(e.gd);
                Archive::readGrid(e.grid, e.gd, in_);
                named[e.gd.uniqueName()] = e.grid;
            }
            entries_.push_back(std::move(e));
        }
        if (!inputHasGridOffsets())
            for (const auto& e : entries_) connectInstance(e.gd, named);
    }

    [[nodiscard]] bool has(const std::string& name) const { return find(name) != nullptr; }

    /// The grid's metadata and transform (with grid offsets, without its voxels).
    openvdb::GridBase::Ptr metadata(const std::string& name) { return metadata(*find(name)); }
    /// The whole grid.
    openvdb::GridBase::Ptr grid(const std::string& name) { return grid(*find(name), 0); }

    std::vector<VdbGrid> list() {
        std::vector<VdbGrid> out;
        for (const auto& e : entries_) {
            const openvdb::GridBase::Ptr meta = metadata(e);
            std::optional<VdbGrid> g;
            if (inputHasGridOffsets()) g = stats_from_metadata(*meta);
            if (!g) g = stats_from_grid(*grid(e, 0));
            g->name = e.gd.gridName();
            g->type = meta->valueType();
            out.push_back(std::move(*g));
        }
        return out;
    }

private:
    struct Entry {
        openvdb::io::GridDescriptor gd;
        openvdb::GridBase::Ptr grid;  // without grid offsets: read with the file
    };

    [[nodiscard]] const Entry* find(const std::string& name) const {
        for (const auto& e : entries_)
            if (e.gd.gridName() == name) return &e;
        return nullptr;
    }

    static openvdb::GridBase::Ptr create(const openvdb::io::GridDescriptor& gd) {
        openvdb::GridBase::Ptr grid = openvdb::GridBase::createGrid(gd.gridType());
        grid->setSaveFloatAsHalf(gd.saveFloatAsHalf());
        return grid;
    }

    openvdb::GridBase::Ptr metadata(const Entry& e) {
        if (e.grid) return e.grid;
        if (fileVersion() < openvdb::OPENVDB_FILE_VERSION_GRID_INSTANCING)
            return grid(e, 0);  // older files store the transform after the topology
        openvdb::GridBase::Ptr g = create(e.gd);
        e.gd.seekToGrid(in_);
        readGridCompression(in_);
        g->readMeta(in_);
        g->readTransform(in_);
        if (g->getName().empty()) g->setName(e.gd.gridName());
        return g;
    }

    openvdb::GridBase::Ptr grid(const Entry& e, int depth) {
        if (e.grid) return e.grid;
        if (e.gd.isInstance()) {  // shares the tree of its parent grid
            const Entry* parent = nullptr;
            for (const auto& p : entries_)
                if (p.gd.uniqueName() == e.gd.instanceParentName()) parent = &p;
            if (!parent || depth > 0)
                throw Error(subject_, "corrupt file: grid '" + e.gd.gridName() +
                                          "' is an instance of a missing or instanced grid");
            openvdb::GridBase::Ptr g = metadata(e);
            g->setTree(grid(*parent, depth + 1)->baseTreePtr());
            return g;
        }
        openvdb::GridBase::Ptr g = create(e.gd);
        e.gd.seekToGrid(in_);
        Archive::readGrid(g, e.gd, in_);
        if (g->getName().empty()) g->setName(e.gd.gridName());
        return g;
    }

    const std::string& subject_;
    std::ifstream in_;
    openvdb::io::StreamMetadata::Ptr stream_meta_;
    std::vector<Entry> entries_;
};

/// "'density' (float), 'v' (vec3s)" or "no grids".
std::string describe(const std::vector<VdbGrid>& grids) {
    if (grids.empty()) return "no grids";
    std::string s;
    for (const auto& g : grids) {
        if (!s.empty()) s += ", ";
        s += "'" + g.name + "' (" + g.type + ")";
    }
    return s;
}

/// Refuses a densified box over kMaxVolumeBytes (float32), before anything is allocated.
void check_box_size(const std::string& subject, const std::string& name, const openvdb::Coord& lo,
                    const openvdb::Coord& hi) {
    std::array<std::int64_t, 3> dims{};
    double bytes = 4.0;
    for (int a = 0; a < 3; ++a) {
        dims[a] = std::max<std::int64_t>(std::int64_t{hi[a]} - lo[a] + 1, 2);
        bytes *= static_cast<double>(dims[a]);
    }
    if (bytes > static_cast<double>(kMaxVolumeBytes))
        throw Error(subject,
                    "grid '" + name + "': the active bounding box " + coord_text(lo) + " to " +
                        coord_text(hi) + " is " + std::to_string(dims[0]) + "x" + std::to_string(dims[1]) +
                        "x" + std::to_string(dims[2]) + " voxels, which as float32 needs " +
                        std::to_string(static_cast<std::uint64_t>(bytes / 1073741824.0)) +
                        " GiB, more than the " + std::to_string(kMaxVolumeBytes >> 30) + " GiB limit");
}

// ================================================================ sending

/// The grid's linear index-to-world transform for a box starting at `lo`: origin, then the axes.
void send_placement(Sender& out, const std::string& subject, const std::string& name,
                    const openvdb::math::Transform& xform, const openvdb::Coord& lo) {
    const openvdb::Vec3d base = lo.asVec3d();
    const openvdb::Vec3d o = xform.indexToWorld(base);
    if (!std::isfinite(o[0]) || !std::isfinite(o[1]) || !std::isfinite(o[2]))
        throw Error(subject, "grid '" + name + "': the transform places the volume at a non-finite position");
    for (int a = 0; a < 3; ++a) out.pod(o[a]);
    for (int a = 0; a < 3; ++a) {
        openvdb::Vec3d step = base;
        step[a] += 1.0;
        const openvdb::Vec3d w = xform.indexToWorld(step) - o;
        for (int b = 0; b < 3; ++b) out.pod(w[b]);
    }
}

/// Sends the grid densified over its active bounding box: dims, placement, then the float32
/// values (x fastest) in z slabs, so that only the parent holds the whole dense volume.
template <class GridT>
void send_dense(Sender& out, const std::string& subject, const std::string& name, const GridT& grid) {
    const openvdb::CoordBBox active = grid.evalActiveVoxelBoundingBox();
    if (grid.activeVoxelCount() == 0 || active.empty())
        throw Error(subject, "grid '" + name + "' has no active voxels (an empty grid)");
    check_box_size(subject, name, active.min(), active.max());

    // Extend an axis one voxel thick to two voxels.
    openvdb::Coord lo = active.min(), hi = active.max();
    std::string thin;
    for (int a = 0; a < 3; ++a) {
        if (lo[a] != hi[a]) continue;
        if (hi[a] < std::numeric_limits<openvdb::Int32>::max())
            ++hi[a];
        else
            --lo[a];
        thin += thin.empty() ? "" : ", ";
        thin += "xyz"[a];
    }
    if (!thin.empty())
        warn(subject + ": grid '" + name + "' is one voxel thick along " + thin +
             "; extended by one voxel there (fathom needs two samples per axis)");

    const std::array<std::int64_t, 3> dims{std::int64_t{hi.x()} - lo.x() + 1,
                                           std::int64_t{hi.y()} - lo.y() + 1,
                                           std::int64_t{hi.z()} - lo.z() + 1};
    out.tag(Tag::volume);
    for (const auto d : dims) out.pod(d);
    send_placement(out, subject, name, grid.transform(), lo);
    // Slabs of about 4 M values (at least one z layer); LayoutXYZ is x fastest, fathom's order.
    const std::int64_t layer = dims[0] * dims[1];
    const std::int64_t per_slab = std::max<std::int64_t>(1, (std::int64_t{1} << 22) / layer);
    std::vector<float> slab(static_cast<std::size_t>(layer * std::min(per_slab, dims[2])));
    for (std::int64_t z0 = 0; z0 < dims[2]; z0 += per_slab) {
        const std::int64_t nz = std::min(per_slab, dims[2] - z0);
        const openvdb::CoordBBox box(
            openvdb::Coord(lo.x(), lo.y(), lo.z() + static_cast<openvdb::Int32>(z0)),
            openvdb::Coord(hi.x(), hi.y(), lo.z() + static_cast<openvdb::Int32>(z0 + nz - 1)));
        openvdb::tools::Dense<float, openvdb::tools::LayoutXYZ> dense(box, slab.data());
        openvdb::tools::copyToDense(grid, dense, /*serial=*/true);
        out.bytes(slab.data(), static_cast<std::size_t>(layer * nz) * sizeof(float));
    }
}

/// In the child: reads grid `name` and sends it densified.
void send_grid(Sender& out, const std::string& subject, const std::filesystem::path& path,
               const std::string& name) {
    init_openvdb();
    VdbArchive file(subject, path);
    if (!file.has(name))
        throw Error(subject, "no grid named '" + name + "'; the file holds " + describe(file.list()));

    // Metadata and transform first: refuse a wrong type, a frustum or an oversized box before
    // reading the voxels.
    const openvdb::GridBase::Ptr meta = file.metadata(name);
    const std::string type = meta->valueType();
    if (type != "float" && type != "double")
        throw Error(subject, "grid '" + name + "' holds " + type +
                                 " values; fathom reads float and double (scalar) grids only");
    if (!meta->transform().isLinear())
        throw Error(subject, "grid '" + name + "' has a non-linear (" + meta->transform().mapType() +
                                 ") transform; fathom reads grids with linear (affine) transforms only");
    if (const auto stats = stats_from_metadata(*meta); stats && stats->active_voxels > 0)
        check_box_size(subject, name,
                       openvdb::Coord(static_cast<openvdb::Int32>(stats->bbox_min[0]),
                                      static_cast<openvdb::Int32>(stats->bbox_min[1]),
                                      static_cast<openvdb::Int32>(stats->bbox_min[2])),
                       openvdb::Coord(static_cast<openvdb::Int32>(stats->bbox_max[0]),
                                      static_cast<openvdb::Int32>(stats->bbox_max[1]),
                                      static_cast<openvdb::Int32>(stats->bbox_max[2])));

    const openvdb::GridBase::Ptr grid = file.grid(name);
    if (const auto g = openvdb::gridConstPtrCast<openvdb::FloatGrid>(grid))
        return send_dense(out, subject, name, *g);
    if (const auto g = openvdb::gridConstPtrCast<openvdb::DoubleGrid>(grid))
        return send_dense(out, subject, name, *g);
    throw Error(subject, "grid '" + name + "' holds " + grid->valueType() + " values in a " + grid->type() +
                             " tree; fathom reads float and double grids of the standard tree only");
}

/// The grid list.
void send_list(Sender& out, const std::string& subject, const std::filesystem::path& path) {
    init_openvdb();
    const std::vector<VdbGrid> grids = VdbArchive(subject, path).list();
    out.tag(Tag::list);
    out.pod(static_cast<std::uint64_t>(grids.size()));
    for (const auto& g : grids) {
        out.str(g.name);
        out.str(g.type);
        out.pod(g.active_voxels);
        out.pod(g.bbox_min);
        out.pod(g.bbox_max);
    }
}

}  // namespace
}  // namespace fathom::vdb

extern "C" __attribute__((visibility("default"))) void fathom_vdb_child(
    int fd, int op, const char* subject_text, const char* path_text, std::uint64_t size, const char* grid) {
    using namespace fathom;
    using namespace fathom::vdb;
    static_assert(std::is_same_v<decltype(fathom_vdb_child), ChildFn>);
    const std::string subject = subject_text;
    const std::filesystem::path path = path_text;
    Sender out(fd);
    try {
        // fork copies only the calling thread: TBB (used by OpenVDB's tree statistics) on one thread.
        const tbb::global_control one_thread(tbb::global_control::max_allowed_parallelism, 1);
        set_warning_sink([&out](const std::string& m) {
            out.tag(Tag::warning);
            out.str(m);
        });
        guarded(subject, [&] {
            check_structure(subject, path, size);
            if (op == static_cast<int>(Op::list))
                send_list(out, subject, path);
            else
                send_grid(out, subject, path, grid);
        });
    } catch (const Error& e) {
        out.tag(Tag::error);
        out.str(e.reason());
    } catch (...) {
        out.tag(Tag::error);
        out.str("OpenVDB failed reading the file");
    }
}
