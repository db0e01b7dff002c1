// The boundary between the library's DICOM functions (src/io/dicom_reader.cpp)
// and fathom's DICOM module (modules/dicom/dicom_module.cpp, GDCM), which the
// library loads with dlopen on the first DICOM read and calls in-process: one
// Call per read, its warnings through `warn`, its failure as the subject and
// reason of the fathom::Error the library then throws. Both sides are built from this header by the same
// compiler.
#pragma once

#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "fathom/io.h"
#include "fathom/volume.h"

namespace fathom::dicom {

inline constexpr const char* kModuleName = "fathom-dicom.so";
/// The module's one exported function: void fathom_dicom_call(Call&) noexcept.
inline constexpr const char* kEntry = "fathom_dicom_call";

struct Call {
    enum class Kind { list, read, read_files };
    Kind kind = Kind::read;
    std::filesystem::path path;                // list, read
    std::string series_uid;                    // read
    std::vector<std::filesystem::path> files;  // read_files
    std::string subject;                       // read_files; the subject of errors without one
    std::function<void(const std::string&)> warn;
    // out
    Volume volume;
    std::vector<DicomSeries> series;
    bool failed = false;
    std::string error_subject, error_reason;
};

using Entry = void(Call&) noexcept;

}  // namespace fathom::dicom
