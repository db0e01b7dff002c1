#include "io/shared_library.h"

#include <dlfcn.h>

#include <cstdlib>

#include "fathom/error.h"

namespace fathom::io {

void* load_library(const std::string& soname, const std::string& what, const std::string& subject) {
    void* handle = dlopen(soname.c_str(), RTLD_NOW | RTLD_LOCAL);
    if (handle == nullptr) {
        const char* why = dlerror();
        throw Error(subject, "cannot load " + what + "'s " + soname +
                                 (why != nullptr ? std::string(": ") + why : std::string()));
    }
    return handle;
}

void* library_function(void* handle, const char* name, const std::string& soname, const std::string& what,
                       const std::string& subject) {
    void* f = dlsym(handle, name);
    if (f == nullptr)
        throw Error(subject, what + "'s " + soname + " has no function " + name +
                                 " (a version other than the one fathom was built with?)");
    return f;
}

std::filesystem::path find_module(const std::string& name, const char* env,
                                  const std::vector<std::string>& known, const std::string& purpose,
                                  const std::string& what, const std::string& subject) {
    const std::string head = "cannot " + purpose + ": fathom's " + what + " ";
    if (const char* set = std::getenv(env); set != nullptr && set[0] != '\0') {
        if (!std::filesystem::exists(set)) throw Error(subject, head + set + " (" + env + ") does not exist");
        return set;
    }
    std::vector<std::filesystem::path> dirs;
    Dl_info info{};
    if (::dladdr(reinterpret_cast<void*>(&find_module), &info) != 0 && info.dli_fname != nullptr &&
        info.dli_fname[0] == '/')
        dirs.push_back(std::filesystem::path(info.dli_fname).parent_path());
    std::error_code ec;
    if (const auto exe = std::filesystem::read_symlink("/proc/self/exe", ec); !ec)
        dirs.push_back(exe.parent_path());
    std::vector<std::filesystem::path> candidates;
    for (const auto& d : dirs) {
        candidates.push_back(d / name);
        candidates.push_back(d / ".." / "lib" / "fathom" / name);
    }
    for (const auto& k : known)
        if (!k.empty()) candidates.emplace_back(k);
    std::string looked;
    for (const auto& c : candidates) {
        if (std::filesystem::is_regular_file(c, ec)) return c;
        looked += (looked.empty() ? "" : ", ") + c.string();
    }
    throw Error(subject, head + name + " is not installed (looked for " + looked + ")");
}

}  // namespace fathom::io
