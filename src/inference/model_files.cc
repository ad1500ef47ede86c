#include "superdyna/inference/model_files.h"

#include <cstdlib>
#include <system_error>

#include "superdyna/core/error.h"

namespace superdyna::inference {

namespace fs = std::filesystem;

std::vector<fs::path> modelSearchDirs() {
  std::vector<fs::path> dirs;
  if (const char* env = std::getenv(kModelDirVariable); env != nullptr && *env != '\0') {
    dirs.emplace_back(env);
  }
  dirs.emplace_back(SUPERDYNA_REPO_MODEL_DIR);
  return dirs;
}

fs::path findModel(const std::string& name) {
  const fs::path given(name);
  std::error_code ec;
  if (given.has_parent_path()) {
    if (fs::is_regular_file(given, ec)) return given;
    throw InputError(InputLocation(given), "model file not found");
  }
  std::string looked;
  for (const auto& dir : modelSearchDirs()) {
    const fs::path candidate = dir / given;
    if (fs::is_regular_file(candidate, ec)) return candidate;
    looked += "\n  " + candidate.string();
  }
  const char* env = std::getenv(kModelDirVariable);
  throw InputError("model '" + name + "' not found; looked at:" + looked + "\n" +
                   (env == nullptr || *env == '\0'
                        ? std::string(kModelDirVariable) + " is not set. "
                        : std::string()) +
                   "Put the file into one of these folders or set " + kModelDirVariable +
                   " to the folder holding it (docs/concepts/learned-features.md says how to "
                   "get or export each model).");
}

fs::path findModel(const std::string& name, const std::string& how_to_get) {
  try {
    return findModel(name);
  } catch (const InputError& e) {
    throw InputError(std::string(e.what()) + "\n" + how_to_get);
  }
}

}  // namespace superdyna::inference
