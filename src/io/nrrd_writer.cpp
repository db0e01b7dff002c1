// write_nrrd: an attached NRRD (NRRD0004) with the volume's type,
// components (a leading "vector" axis), LPS space directions and origin, and
// raw or gzip data in native (little-endian) byte order. Numbers are printed
// with 17 significant digits, so read_nrrd gives the same bits back.
#include <bit>
#include <cstdio>
#include <sstream>
#include <string>
#include <vector>

#include <zlib.h>

#include "fathom/error.h"
#include "fathom/io.h"

#include "io/atomic_file.h"

namespace fathom {
namespace {

std::string number(double x) {
    char buf[40];
    std::snprintf(buf, sizeof buf, "%.17g", x);
    return buf;
}

/// NRRD's type names are dtype_name's except for the two float types.
std::string nrrd_type(DType t) {
    if (t == DType::f32) return "float";
    if (t == DType::f64) return "double";
    return std::string(dtype_name(t));
}

std::string header(const Volume& v, bool gzip) {
    const bool vec = v.components() > 1;
    const Mat3& m = v.axes();
    const Vec3& o = v.origin();
    std::ostringstream h;
    h << "NRRD0004\n# Written by fathom " FATHOM_VERSION "\n";
    h << "type: " << nrrd_type(v.dtype()) << "\n";
    h << "dimension: " << (vec ? 4 : 3) << "\n";
    h << "space: left-posterior-superior\n";
    h << "sizes:";
    if (vec) h << ' ' << v.components();
    for (auto n : v.dims()) h << ' ' << n;
    h << "\nspace directions:";
    if (vec) h << " none";
    for (int c = 0; c < 3; ++c)
        h << " (" << number(m.m[0][c]) << ',' << number(m.m[1][c]) << ',' << number(m.m[2][c]) << ')';
    h << "\nkinds:" << (vec ? " vector" : "") << " domain domain domain\n";
    if (dtype_size(v.dtype()) > 1)
        h << "endian: " << (std::endian::native == std::endian::little ? "little" : "big") << "\n";
    h << "encoding: " << (gzip ? "gzip" : "raw") << "\n";
    h << "space origin: (" << number(o.x) << ',' << number(o.y) << ',' << number(o.z) << ")\n\n";
    return h.str();
}

/// Streams the bytes through zlib's gzip wrapper into the file.
void write_gzip(io::AtomicFile& out, const std::byte* data, std::size_t size) {
    z_stream zs{};
    if (deflateInit2(&zs, 6, Z_DEFLATED, 15 + 16, 8, Z_DEFAULT_STRATEGY) != Z_OK)
        throw Error(out.target().string(), "cannot initialise gzip compression");
    std::vector<unsigned char> buf(std::size_t{1} << 20);
    std::size_t done = 0;
    int rc = Z_OK;
    do {
        const std::size_t chunk = std::min<std::size_t>(size - done, std::size_t{1} << 30);
        zs.next_in = reinterpret_cast<Bytef*>(const_cast<std::byte*>(data + done));
        zs.avail_in = static_cast<uInt>(chunk);
        done += chunk;
        const int flush = done == size ? Z_FINISH : Z_NO_FLUSH;
        do {
            zs.next_out = buf.data();
            zs.avail_out = static_cast<uInt>(buf.size());
            rc = deflate(&zs, flush);
            if (rc == Z_STREAM_ERROR) {
                deflateEnd(&zs);
                throw Error(out.target().string(), "gzip compression failed");
            }
            out.write(buf.data(), buf.size() - zs.avail_out);
        } while (zs.avail_out == 0);
    } while (done < size);
    deflateEnd(&zs);
    if (rc != Z_STREAM_END) throw Error(out.target().string(), "gzip compression did not finish");
}

}  // namespace

void write_nrrd(const std::filesystem::path& path, const Volume& volume, bool gzip) {
    if (volume.num_nodes() == 0) throw Error(path.string(), "cannot write an empty volume");
    io::AtomicFile out(path);
    const std::string h = header(volume, gzip);
    out.write(h.data(), h.size());
    if (gzip)
        write_gzip(out, volume.bytes(), volume.size_bytes());
    else
        out.write(volume.bytes(), volume.size_bytes());
    out.commit();
}

}  // namespace fathom
