#include "superdyna/io/yaml_file.h"

#include <fmt/format.h>

#include <fstream>
#include <sstream>
#include <utility>

#include "superdyna/io/text_table.h"

namespace superdyna::io {

namespace fs = std::filesystem;

namespace {

/// Blanks an OpenCV "%YAML:1.0" first line. The line is emptied rather than removed so that
/// yaml-cpp's line numbers stay those of the file.
void blankOpenCvDirective(std::string& text) {
  if (!text.starts_with("%YAML:")) return;
  const std::size_t end = text.find('\n');
  text.erase(0, end == std::string::npos ? text.size() : end);
}

int lineOf(const YAML::Mark& mark) {
  return mark.line >= 0 ? mark.line + 1 : 0;
}

}  // namespace

YamlFile YamlFile::load(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  if (!in) {
    throw InputError(InputLocation{file},
                     fs::exists(file) ? "cannot open file" : "file does not exist");
  }
  std::stringstream buffer;
  buffer << in.rdbuf();
  return parse(buffer.str(), file);
}

YamlFile YamlFile::parse(std::string text, const fs::path& file) {
  blankOpenCvDirective(text);
  YAML::Node root;
  try {
    root = YAML::Load(text);
  } catch (const YAML::Exception& e) {
    throw InputError(InputLocation{file, lineOf(e.mark)}, "YAML syntax error: " + e.msg);
  }
  if (!root.IsMap()) {
    throw InputError(InputLocation{file}, "expected a YAML map of 'key: value' lines");
  }
  return YamlFile(file, std::move(root));
}

bool YamlFile::has(const std::string& key) const {
  return root_[key].IsDefined();
}

YAML::Node YamlFile::child(const YAML::Node& parent, const std::string& key,
                           const std::string& field) const {
  if (!parent.IsMap()) {
    throw InputError(at(parent, field), "expected a map containing '" + key + "'");
  }
  YAML::Node node = parent[key];
  if (!node.IsDefined()) {
    // A missing top-level key has no line; a missing nested key is reported at its parent.
    const int line = parent.is(root_) ? 0 : lineOf(parent.Mark());
    throw InputError(InputLocation{file_, line, field}, "missing field");
  }
  return node;
}

std::string YamlFile::scalar(const YAML::Node& node, const std::string& field) const {
  if (!node.IsScalar()) throw InputError(at(node, field), "expected a single value");
  return node.Scalar();
}

double YamlFile::number(const YAML::Node& node, const std::string& field) const {
  return parseFiniteDouble(scalar(node, field), at(node, field));
}

std::vector<double> YamlFile::numbers(const YAML::Node& node, const std::string& field) const {
  if (!node.IsSequence()) throw InputError(at(node, field), "expected a list '[a, b, ...]'");
  std::vector<double> values;
  values.reserve(node.size());
  for (std::size_t i = 0; i < node.size(); ++i) {
    values.push_back(number(node[i], fmt::format("{}[{}]", field, i)));
  }
  return values;
}

InputLocation YamlFile::at(const YAML::Node& node, const std::string& field) const {
  return InputLocation{file_, lineOf(node.Mark()), field};
}

}  // namespace superdyna::io
