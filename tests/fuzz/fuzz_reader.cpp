// libFuzzer target for one volume reader (FATHOM_FUZZ_READER names it):
// the input bytes become a file with the reader's extension and are read;
// fathom::Error is the expected outcome for bad input, anything else (a
// crash, a sanitizer report, another exception, a leak) is a finding.
// Built by tests/fuzz/CMakeLists.txt with clang; run by tests/fuzz/run.sh.
#include <pthread.h>
#include <sanitizer/common_interface_defs.h>
#include <unistd.h>

#include <csignal>
#include <cstddef>
#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <string>

#include "fathom/error.h"
#include "fathom/io.h"
#include "fathom/log.h"

namespace {

namespace fs = std::filesystem;

#define FATHOM_STR2(x) #x
#define FATHOM_STR(x) FATHOM_STR2(x)
const std::string kReader = FATHOM_STR(FATHOM_FUZZ_READER);

std::string extension() {
    if (kReader == "nrrd") return ".nrrd";
    if (kReader == "metaimage") return ".mha";
    if (kReader == "slc") return ".slc";
    if (kReader == "vtk") return ".vtk";
    if (kReader == "vti") return ".vti";
    if (kReader == "nifti") return ".nii";
    if (kReader == "nifti_gz") return ".nii.gz";
    if (kReader == "dicom") return ".dcm";
    if (kReader == "vdb") return ".vdb";
    return ".raw";
}

fathom::Volume read(const fs::path& p) {
    if (kReader == "nrrd") return fathom::read_nrrd(p);
    if (kReader == "metaimage") return fathom::read_metaimage(p);
    if (kReader == "slc") return fathom::read_slc(p);
    if (kReader == "vtk") return fathom::read_legacy_vtk(p);
    if (kReader == "vti") return fathom::read_vti(p);
    if (kReader == "nifti" || kReader == "nifti_gz") return fathom::read_nifti(p);
    if (kReader == "dicom") return fathom::read_dicom(p);
    if (kReader == "vdb") return fathom::read_vdb(p);
    return fathom::read_volume(p);
}

/// The OpenVDB reader reads in a child process (fork) so that OpenVDB's own memory errors stay
/// there; the parent gets an Error. That child must die quietly, not report the input as a
/// crash through libFuzzer's death callback and signal handlers inherited from the parent.
void quiet_child() {
    __sanitizer_set_death_callback(nullptr);
    for (const int sig : {SIGABRT, SIGSEGV, SIGBUS, SIGILL, SIGFPE}) std::signal(sig, SIG_DFL);
}

}  // namespace

extern "C" int LLVMFuzzerInitialize(int*, char***) {
    fathom::set_warning_sink({});
    pthread_atfork(nullptr, nullptr, quiet_child);
    return 0;
}

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
    const fs::path dir = fs::exists("/dev/shm") ? fs::path("/dev/shm") : fs::temp_directory_path();
    const fs::path file = dir / ("fathom_fuzz_" + std::to_string(::getpid()) + extension());
    if (std::FILE* f = std::fopen(file.c_str(), "wb")) {
        std::fwrite(data, 1, size, f);
        std::fclose(f);
    } else {
        return 0;
    }
    try {
        (void)read(file);
    } catch (const fathom::Error&) {
        // the expected outcome for bad input
    }
    std::error_code ec;
    fs::remove(file, ec);
    return 0;
}
