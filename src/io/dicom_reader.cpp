// The library's DICOM functions (include/fathom/io.h): the reader itself is
// fathom's DICOM module (modules/dicom/dicom_module.cpp, fathom-dicom.so,
// GDCM), loaded with dlopen on the first DICOM read and called in-process
// (src/io/dicom_module.h). Processes that read no DICOM never load GDCM,
// whose DICOM dictionary is built when it is loaded.
#include <string>
#include <utility>
#include <vector>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"

#include "io/dicom_module.h"
#include "io/shared_library.h"

#ifndef FATHOM_DICOM_MODULE_BUILD
#define FATHOM_DICOM_MODULE_BUILD ""
#endif
#ifndef FATHOM_DICOM_MODULE_INSTALL
#define FATHOM_DICOM_MODULE_INSTALL ""
#endif

namespace fathom {
namespace {

/// The module's entry point, the module loaded on first use
/// ($FATHOM_DICOM_MODULE, else io::find_module's places).
dicom::Entry* module_entry(const std::string& subject) {
    static dicom::Entry* const entry = [&] {
        const std::string path = io::find_module(dicom::kModuleName, "FATHOM_DICOM_MODULE",
                                                 {FATHOM_DICOM_MODULE_BUILD, FATHOM_DICOM_MODULE_INSTALL},
                                                 "read DICOM files", "DICOM module", subject)
                                     .string();
        void* handle = io::load_library(path, "fathom", subject);
        return reinterpret_cast<dicom::Entry*>(
            io::library_function(handle, dicom::kEntry, path, "fathom", subject));
    }();
    return entry;
}

/// Runs the call in the module: its warnings through this process's sink,
/// its failure as one Error.
void run(dicom::Call& call) {
    call.warn = [](const std::string& m) { warn(m); };
    module_entry(call.subject)(call);
    if (call.failed) throw Error(std::move(call.error_subject), std::move(call.error_reason));
}

}  // namespace

std::vector<DicomSeries> list_dicom_series(const std::filesystem::path& path) {
    dicom::Call call;
    call.kind = dicom::Call::Kind::list;
    call.path = path;
    call.subject = path.string();
    run(call);
    return std::move(call.series);
}

Volume read_dicom(const std::filesystem::path& path, const std::string& series_uid) {
    dicom::Call call;
    call.kind = dicom::Call::Kind::read;
    call.path = path;
    call.series_uid = series_uid;
    call.subject = path.string();
    run(call);
    return std::move(call.volume);
}

Volume read_dicom_files(const std::vector<std::filesystem::path>& files, const std::string& subject) {
    dicom::Call call;
    call.kind = dicom::Call::Kind::read_files;
    call.files = files;
    call.subject = subject;
    run(call);
    return std::move(call.volume);
}

}  // namespace fathom
