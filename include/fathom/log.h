// Warnings from the library (a raw file longer than its layout, ...): sent to
// a replaceable sink; the default writes "fathom: warning: MESSAGE" to stderr.
#pragma once

#include <functional>
#include <string>

namespace fathom {

using WarningSink = std::function<void(const std::string&)>;

/// Replaces the sink; returns the previous one. An empty function silences warnings.
WarningSink set_warning_sink(WarningSink sink);
void warn(const std::string& message);

}  // namespace fathom
