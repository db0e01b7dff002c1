// DICOM series reader (GDCM).
#include "fathom/error.h"
#include "fathom/io.h"

namespace fathom {

std::vector<DicomSeries> list_dicom_series(const std::filesystem::path& path) {
    throw Error(path.string(), "DICOM: not implemented yet");
}
Volume read_dicom(const std::filesystem::path& path, const std::string&) {
    throw Error(path.string(), "DICOM: not implemented yet");
}
Volume read_dicom_files(const std::vector<std::filesystem::path>&, const std::string& subject) {
    throw Error(subject, "DICOM: not implemented yet");
}

}  // namespace fathom
