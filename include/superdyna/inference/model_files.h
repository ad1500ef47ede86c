#pragma once
// Where network files are found. Models are not part of the repository; users export or download
// them (docs/concepts/learned-features.md, "Models") and put them in one of the searched folders.

#include <filesystem>
#include <string>
#include <vector>

namespace superdyna::inference {

/// Name of the environment variable naming a folder of model files.
inline constexpr const char* kModelDirVariable = "SUPERDYNA_MODEL_DIR";

/// The folders findModel() searches, in order: $SUPERDYNA_MODEL_DIR (when set and non-empty),
/// then the repository's models/ folder (the path fixed at build time).
std::vector<std::filesystem::path> modelSearchDirs();

/// The model file `name`. A name with a folder part ("exports/superpoint.onnx", an absolute
/// path) is used as given; a bare file name is looked up in modelSearchDirs(). Throws InputError
/// listing every place looked at and how to get the model when it is not found.
std::filesystem::path findModel(const std::string& name);
/// As findModel(name); its InputError gains `how_to_get` on a line of its own (where a model of
/// this kind comes from).
std::filesystem::path findModel(const std::string& name, const std::string& how_to_get);

}  // namespace superdyna::inference
