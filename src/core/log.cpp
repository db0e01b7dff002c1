#include "fathom/log.h"

#include <cstdio>
#include <mutex>
#include <utility>

namespace fathom {
namespace {
std::mutex g_mutex;
WarningSink g_sink = [](const std::string& m) { std::fprintf(stderr, "fathom: warning: %s\n", m.c_str()); };
}  // namespace

WarningSink set_warning_sink(WarningSink sink) {
    std::lock_guard lock(g_mutex);
    return std::exchange(g_sink, std::move(sink));
}

void warn(const std::string& message) {
    std::lock_guard lock(g_mutex);
    if (g_sink) g_sink(message);
}

}  // namespace fathom
