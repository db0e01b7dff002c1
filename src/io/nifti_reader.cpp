// NIfTI-1/2 reader (libnifti2, Debian package libnifti2-dev).
//
// fathom reads the fixed header (348 bytes for NIfTI-1, 540 for NIfTI-2;
// decompressed when the file is gzip, found by its content, not its name)
// and checks its size, sizeof_hdr, datatype and dims, so that short headers,
// corrupt gzip streams and impossible dims get a clear reason (libnifti
// would print its reasons on stderr, silenced here with debug level 0, and
// silently clamps some fields: a negative dim becomes 1). libnifti2 then
// converts the header (nifti_convert_n1hdr2nim / n2hdr2nim): byte order,
// NIfTI-1/NIfTI-2/Analyze 7.5, scaling, and the qform quaternion → matrix,
// and finds a pair's .img (.img.gz) beside its .hdr. The samples are read by
// io::read_grid (raw or gzip, swapped to native order, NaN/Inf refused)
// straight into the Volume: the data are held once, and truncated files and
// corrupt gzip streams get fathom's precise messages.
//
// Placement (SPEC §2): the sform when sform_code > 0, else the qform when
// qform_code > 0, else diag(pixdim) with origin 0 (NIfTI "method 1"); the
// 4×4 matrix maps (i,j,k) to RAS+ and is turned into LPS by negating its x
// and y rows; xyz units in metres or microns are scaled to millimetres.
// Rotated, sheared and flipped matrices are kept as they are.
#include <nifti2_io.h>

#include <array>
#include <cmath>
#include <cstdint>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <memory>
#include <mutex>
#include <optional>
#include <string>
#include <string_view>
#include <utility>

#include <zlib.h>

#include "fathom/error.h"
#include "fathom/io.h"

#include "io/io_util.h"

namespace fathom {
namespace {

constexpr std::size_t kNifti1Size = 348;
constexpr std::size_t kNifti2Size = 540;
constexpr int kMsbFirst = 2;  // nifti_image::byteorder of big-endian files (MSB_FIRST, private to libnifti)

bool is_gzip(std::string_view head) {
    return head.size() >= 2 && static_cast<unsigned char>(head[0]) == 0x1f &&
           static_cast<unsigned char>(head[1]) == 0x8b;
}

/// The first `n` bytes of a file, decompressed when it is gzip-compressed
/// (fewer when the stream is shorter). Corrupt streams are errors.
std::string header_prefix(const std::string& subject, const std::string& file, std::size_t n, bool& gz) {
    std::string head = io::read_prefix(subject, file, n);
    gz = is_gzip(head);
    if (!gz) return head;
    gzFile f = gzopen(file.c_str(), "rb");
    if (f == nullptr) throw Error(subject, "cannot open " + file);
    std::string out(n, '\0');
    const int got = gzread(f, out.data(), static_cast<unsigned>(n));
    int errnum = Z_OK;
    const char* msg = gzerror(f, &errnum);
    std::string why = msg != nullptr ? msg : "zlib error";
    if (why.starts_with(file + ": ")) why.erase(0, file.size() + 2);  // gzerror names the file
    gzclose(f);
    if (got < 0 || (errnum != Z_OK && errnum != Z_BUF_ERROR))
        throw Error(subject,
                    "corrupt gzip stream in the first " + std::to_string(n) + " bytes (the header): " + why);
    out.resize(static_cast<std::size_t>(got));
    return out;
}

template <class T>
T load(std::string_view bytes, std::size_t offset, bool swap) {
    std::array<char, sizeof(T)> b{};
    std::memcpy(b.data(), bytes.data() + offset, sizeof(T));
    if (swap)
        for (std::size_t i = 0; i < sizeof(T) / 2; ++i) std::swap(b[i], b[sizeof(T) - 1 - i]);
    T v;
    std::memcpy(&v, b.data(), sizeof(T));
    return v;
}

std::string dims_text(const std::array<std::int64_t, 8>& dim) {
    std::string s;
    for (std::int64_t a = 1; a <= dim[0]; ++a) {
        if (a > 1) s += " x ";
        s += std::to_string(dim[static_cast<std::size_t>(a)]);
    }
    return s;
}

std::optional<DType> dtype_of(int datatype) {
    switch (datatype) {
        case NIFTI_TYPE_UINT8:
            return DType::u8;
        case NIFTI_TYPE_INT8:
            return DType::i8;
        case NIFTI_TYPE_UINT16:
            return DType::u16;
        case NIFTI_TYPE_INT16:
            return DType::i16;
        case NIFTI_TYPE_UINT32:
            return DType::u32;
        case NIFTI_TYPE_INT32:
            return DType::i32;
        case NIFTI_TYPE_FLOAT32:
            return DType::f32;
        case NIFTI_TYPE_FLOAT64:
            return DType::f64;
        default:
            return std::nullopt;
    }
}

/// The fixed part of the header as stored (not byte-swapped).
struct RawHeader {
    int version = 1;  // 1: 348 bytes, 2: 540 bytes
    std::string bytes;
    std::uint64_t vox_offset = 0;  // as stored (libnifti moves an offset inside the header to its end)
};

/// Reads the fixed part of the header and checks it before libnifti
/// converts it: its size, sizeof_hdr, the NIfTI-2 magic, the datatype and
/// the dimensions (one 3D volume).
RawHeader read_header(const std::string& subject, const std::string& file) {
    bool gz = false;
    const std::string h = header_prefix(subject, file, kNifti2Size, gz);
    const std::string holds = gz ? "the file decompresses to " + std::to_string(h.size()) + " bytes"
                                 : "the file holds " + std::to_string(h.size()) + " bytes";
    if (h.size() < 4)
        throw Error(subject, "truncated header: " + holds + ", a NIfTI header needs 348 or 540");
    int version = 0;
    bool swap = false;
    for (bool s : {false, true}) {
        const auto size = load<std::int32_t>(h, 0, s);
        if (size == static_cast<std::int32_t>(kNifti1Size)) version = 1;
        if (size == static_cast<std::int32_t>(kNifti2Size)) version = 2;
        if (version != 0) {
            swap = s;
            break;
        }
    }
    if (version == 0) {
        throw Error(subject, "not a NIfTI file: sizeof_hdr is " +
                                 std::to_string(load<std::int32_t>(h, 0, false)) +
                                 " (NIfTI-1 has 348, NIfTI-2 540)");
    }
    const std::size_t need = version == 1 ? kNifti1Size : kNifti2Size;
    if (h.size() < need)
        throw Error(subject, "truncated header: " + holds + ", a NIfTI-" + std::to_string(version) +
                                 " header needs " + std::to_string(need));
    if (version == 2) {
        const std::string_view magic(h.data() + 4, 4);
        if (magic != std::string_view("n+2\0", 4) && magic != std::string_view("ni2\0", 4))
            throw Error(subject,
                        "not a NIfTI-2 file: sizeof_hdr is 540 but the magic is not \"n+2\" or \"ni2\"");
    }
    const int datatype = load<std::int16_t>(h, version == 1 ? 70 : 12, swap);
    if (!dtype_of(datatype)) {
        const std::string name = nifti_datatype_string(datatype);
        throw Error(
            subject,
            (name.starts_with("*") ? "unknown NIfTI datatype" : "unsupported NIfTI datatype " + name) +
                " (code " + std::to_string(datatype) +
                "): fathom reads uint8, int8, uint16, int16, uint32, int32, float32 and float64 scalars");
    }
    std::array<std::int64_t, 8> dim{};
    for (std::size_t a = 0; a < 8; ++a)
        dim[a] =
            version == 1 ? load<std::int16_t>(h, 40 + 2 * a, swap) : load<std::int64_t>(h, 16 + 8 * a, swap);
    if (dim[0] < 1 || dim[0] > 7)
        throw Error(subject,
                    "header field dim[0] is " + std::to_string(dim[0]) + ": expected 1 to 7 dimensions");
    for (std::int64_t a = 1; a <= dim[0]; ++a)
        if (dim[static_cast<std::size_t>(a)] < 1)
            throw Error(subject, "header field dim[" + std::to_string(a) + "] is " +
                                     std::to_string(dim[static_cast<std::size_t>(a)]) +
                                     ": every axis needs at least 1 sample");
    for (std::size_t a = static_cast<std::size_t>(dim[0]) + 1; a < 8; ++a) dim[a] = 1;
    if (dim[0] < 3 || dim[1] < 2 || dim[2] < 2 || dim[3] < 2)
        throw Error(subject, "the NIfTI image is " + std::to_string(dim[1]) + " x " + std::to_string(dim[2]) +
                                 " x " + std::to_string(dim[3]) +
                                 " (2D or a single slice): a volume needs at least 2 samples along each of "
                                 "its 3 axes");
    if (dim[4] > 1)
        throw Error(subject,
                    "4D NIfTI with " + std::to_string(dim[4]) + " volumes: only one 3D volume is supported");
    for (std::size_t a = 5; a < 8; ++a)
        if (dim[a] > 1)
            throw Error(subject, std::to_string(dim[0]) + "D NIfTI (" + dims_text(dim) +
                                     "): only one 3D scalar volume is supported (axes 5 to 7 must have one "
                                     "sample; vector or multi-valued voxels are not read)");
    std::uint64_t vox_offset = 0;
    if (version == 1) {
        const float f = load<float>(h, 108, swap);
        if (!std::isfinite(f) || f < 0 || f > 9.0e15f)
            throw Error(subject, "header field vox_offset is " + std::to_string(f) + ": not a byte offset");
        vox_offset = static_cast<std::uint64_t>(f);
    } else {
        const auto i = load<std::int64_t>(h, 168, swap);
        if (i < 0)
            throw Error(subject, "header field vox_offset is " + std::to_string(i) + ": not a byte offset");
        vox_offset = static_cast<std::uint64_t>(i);
    }
    return {version, h.substr(0, need), vox_offset};
}

struct NiftiFree {
    void operator()(nifti_image* p) const { nifti_image_free(p); }
};
struct CFree {
    void operator()(char* p) const { std::free(p); }
};

/// The 4×4 matrix (RAS+) that places the volume, and which one it is.
struct Placement {
    nifti_dmat44 m{};
    const char* source = "";
};

Placement placement_of(const nifti_image& n) {
    if (n.sform_code > 0) return {n.sto_xyz, "sform"};
    if (n.qform_code > 0) return {n.qto_xyz, "qform"};
    Placement p{{}, "pixdim"};
    const std::array<double, 3> d{n.dx, n.dy, n.dz};
    for (int a = 0; a < 3; ++a) {
        const double s = std::abs(d[static_cast<std::size_t>(a)]);
        p.m.m[a][a] = std::isfinite(s) && s > 0 ? s : 1.0;
    }
    p.m.m[3][3] = 1.0;
    return p;
}

/// Millimetres per unit of the header's xyz units (unknown: millimetres).
double mm_per_unit(int xyz_units) {
    switch (xyz_units) {
        case NIFTI_UNITS_METER:
            return 1000.0;
        case NIFTI_UNITS_MICRON:
            return 0.001;
        default:
            return 1.0;
    }
}

void place(const std::string& subject, const nifti_image& n, Volume& v) {
    const Placement p = placement_of(n);
    const double unit = mm_per_unit(n.xyz_units);
    Mat3 m;
    Vec3 origin;
    for (int r = 0; r < 3; ++r) {
        const double sign = r < 2 ? -1.0 : 1.0;  // RAS+ → LPS: negate x and y
        for (int c = 0; c < 3; ++c) m.m[r][c] = sign * unit * p.m.m[r][c];
        origin[r] = sign * unit * p.m.m[r][3];
    }
    for (const auto& row : m.m)
        for (double x : row)
            if (!std::isfinite(x))
                throw Error(subject, std::string("the ") + p.source + " matrix contains a non-finite number");
    if (!std::isfinite(origin.x) || !std::isfinite(origin.y) || !std::isfinite(origin.z))
        throw Error(subject, std::string("the ") + p.source + " offset contains a non-finite number");
    if (m.determinant() == 0.0)
        throw Error(subject, std::string("the ") + p.source + " matrix is singular (zero voxel volume)");
    v.set_axes(m, subject);
    v.set_origin(origin);
}

/// value = slope · stored + inter, as float32 (float64 for float64 data).
Volume rescale(const std::string& subject, const Volume& stored, double slope, double inter) {
    const DType out_type = stored.dtype() == DType::f64 ? DType::f64 : DType::f32;
    Volume out(stored.dims(), out_type, 1);
    const auto n = static_cast<std::size_t>(stored.num_nodes());
    visit_dtype(stored.dtype(), [&]<class T>(T*) {
        const T* in = stored.data<T>();
        if (out_type == DType::f64) {
            double* o = out.data<double>();
            for (std::size_t i = 0; i < n; ++i) o[i] = slope * static_cast<double>(in[i]) + inter;
        } else {
            float* o = out.data<float>();
            for (std::size_t i = 0; i < n; ++i)
                o[i] = static_cast<float>(slope * static_cast<double>(in[i]) + inter);
        }
    });
    try {
        io::check_finite(subject, out);
    } catch (const Error& e) {
        throw Error(subject, "scl_slope " + std::to_string(slope) + " and scl_inter " +
                                 std::to_string(inter) + " give a value out of range: " + e.reason());
    }
    return out;
}

/// The header file: the file named, or the .hdr beside a named .img.
std::string header_file_of(const std::string& subject) {
    const std::string lower = io::to_lower(subject);
    if (!lower.ends_with(".img") && !lower.ends_with(".img.gz")) return subject;
    const std::unique_ptr<char, CFree> found(nifti_findhdrname(subject.c_str()));
    if (!found) throw Error(subject, "no .hdr header file found beside this .img file");
    return found.get();
}

/// libnifti's image description, converted from the header bytes.
std::unique_ptr<nifti_image, NiftiFree> convert(const std::string& subject, const std::string& file,
                                                const RawHeader& h) {
    nifti_image* n = nullptr;
    if (h.version == 1) {
        nifti_1_header n1;
        static_assert(sizeof n1 == kNifti1Size);
        std::memcpy(&n1, h.bytes.data(), sizeof n1);
        n = nifti_convert_n1hdr2nim(n1, file.c_str());
    } else {
        nifti_2_header n2;
        static_assert(sizeof n2 == kNifti2Size);
        std::memcpy(&n2, h.bytes.data(), sizeof n2);
        n = nifti_convert_n2hdr2nim(n2, file.c_str());
    }
    if (n == nullptr) throw Error(subject, "libnifti refuses the header (invalid NIfTI header)");
    return std::unique_ptr<nifti_image, NiftiFree>(n);
}

/// The file holding the samples: the header's own file, or a pair's .img (.img.gz).
std::filesystem::path image_file_of(const std::string& subject, const std::string& header_file, int type) {
    if (type == NIFTI_FTYPE_NIFTI1_1 || type == NIFTI_FTYPE_NIFTI2_1) return header_file;
    const std::unique_ptr<char, CFree> found(nifti_findimgname(header_file.c_str(), type));
    if (found) return found.get();
    std::filesystem::path expected(header_file);
    if (io::to_lower(expected.extension().string()) == ".gz") expected.replace_extension();
    expected.replace_extension(".img");
    throw Error(subject, "image file " + expected.string() +
                             " does not exist (a .hdr header's samples are in the .img file beside it)");
}

}  // namespace

Volume read_nifti(const std::filesystem::path& path) {
    const std::string subject = path.string();
    static std::once_flag quiet;
    std::call_once(quiet, [] { nifti_set_debug_level(0); });  // libnifti reports on stderr otherwise

    io::file_size_checked(subject, path, "file");
    const std::string header_file = header_file_of(subject);
    const RawHeader raw = read_header(subject, header_file);
    const auto nim = convert(subject, header_file, raw);
    const nifti_image& n = *nim;
    const auto dtype = dtype_of(n.datatype);
    if (!dtype) throw Error(subject, "unsupported NIfTI datatype code " + std::to_string(n.datatype));

    const io::GridShape shape{{n.nx, n.ny, n.nz}, *dtype, 1};
    const std::uint64_t bytes = io::grid_bytes(subject, "dim", shape);

    const std::filesystem::path image_file = image_file_of(subject, header_file, n.nifti_type);
    const bool attached = image_file == std::filesystem::path(header_file);
    const std::string what = attached ? "file" : "image file";
    const std::uint64_t size = io::file_size_checked(subject, image_file, what);
    const std::uint64_t offset = raw.vox_offset;
    if (attached && offset < raw.bytes.size())
        throw Error(subject, "header field vox_offset is " + std::to_string(offset) +
                                 ": the samples cannot start inside the " + std::to_string(raw.bytes.size()) +
                                 "-byte header");
    const bool gz = is_gzip(io::read_prefix(subject, image_file, 2));
    io::DataSpec spec;
    spec.big_endian = n.byteorder == kMsbFirst;
    io::DataFile data{image_file, 0, attached};
    if (gz) {
        spec.encoding = io::Encoding::zlib;
        spec.byte_skip = offset;  // vox_offset counts bytes of the decompressed stream
    } else {
        if (size < offset || size - offset < bytes)
            throw Error(subject, "truncated: expected " + std::to_string(bytes) +
                                     " bytes of pixel data from byte " + std::to_string(offset) + " of " +
                                     what + " " + image_file.string() + ", found " +
                                     std::to_string(size < offset ? 0 : size - offset));
        data.start = offset;
    }
    Volume v = io::read_grid(subject, shape, {data}, spec);

    const double slope = n.scl_slope;
    const double inter = std::isfinite(n.scl_inter) ? n.scl_inter : 0.0;
    const bool identity = slope == 0.0 || !std::isfinite(slope) || (slope == 1.0 && inter == 0.0);
    if (!identity) v = rescale(subject, v, slope, inter);
    place(subject, n, v);
    return v;
}

}  // namespace fathom
