#pragma once
// Output-file helpers shared by the commands: never write over an input, write JSON atomically
// enough (whole file or a clear error).

#include <filesystem>
#include <nlohmann/json.hpp>
#include <string>
#include <vector>

namespace superdyna::apps {

/// Throws OptionError when `output` is the same file as one of `inputs` (the user's data is
/// never overwritten by a result).
void requireDistinctOutput(const std::filesystem::path& output,
                           const std::vector<std::filesystem::path>& inputs,
                           const std::string& option);

/// Writes `json` (indented) to `file`; InputError when the file cannot be written.
void writeJson(const std::filesystem::path& file, const nlohmann::json& json);

}  // namespace superdyna::apps
