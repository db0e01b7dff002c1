// OpenVDB reader.
#include "fathom/error.h"
#include "fathom/io.h"

namespace fathom {

std::vector<VdbGrid> list_vdb_grids(const std::filesystem::path& path) {
    throw Error(path.string(), "OpenVDB: not implemented yet");
}
Volume read_vdb(const std::filesystem::path& path, const std::string&) {
    throw Error(path.string(), "OpenVDB: not implemented yet");
}

}  // namespace fathom
