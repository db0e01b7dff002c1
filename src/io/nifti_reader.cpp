// NIfTI-1/2 reader (libnifti2).
#include "fathom/error.h"
#include "fathom/io.h"

namespace fathom {

Volume read_nifti(const std::filesystem::path& path) { throw Error(path.string(), "NIfTI: not implemented yet"); }

}  // namespace fathom
