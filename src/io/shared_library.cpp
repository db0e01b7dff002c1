#include "io/shared_library.h"

#include <dlfcn.h>

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

}  // namespace fathom::io
