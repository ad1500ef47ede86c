#include "commands/output_files.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <fstream>

#include "superdyna/core/atomic_file.h"
#include "superdyna/core/error.h"

namespace superdyna::apps {

namespace fs = std::filesystem;

void requireDistinctOutput(const fs::path& output, const std::vector<fs::path>& inputs,
                           const std::string& option) {
  if (!fs::exists(output)) return;
  for (const fs::path& input : inputs) {
    if (fs::exists(input) && fs::equivalent(output, input)) {
      throw OptionError(
          option, fmt::format("'{}' is an input file; refusing to overwrite it", output.string()));
    }
  }
}

void writeJson(const fs::path& file, const nlohmann::json& json) {
  if (file.has_parent_path()) fs::create_directories(file.parent_path());
  writeFileAtomically(file, json.dump(2) + '\n');
  spdlog::info("results written to {}", file.string());
}

}  // namespace superdyna::apps
