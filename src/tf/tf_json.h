// JSON helpers shared by the transfer-function and scene parsers (private).
#pragma once

#include <filesystem>
#include <string>
#include <string_view>

#include <nlohmann/json.hpp>

#include "fathom/transfer_function.h"

namespace fathom {

TransferFunction tf_from_json(const nlohmann::json& j, const std::string& subject);
nlohmann::json tf_to_json(const TransferFunction& tf);
/// Parses JSON; a syntax error becomes Error(subject, "invalid JSON: ...").
nlohmann::json parse_json_text(std::string_view text, const std::string& subject);
/// Reads a whole text file; Error(path, ...) when it cannot be read.
std::string read_text_file(const std::filesystem::path& path);

}  // namespace fathom
