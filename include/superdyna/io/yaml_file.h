#pragma once
// A YAML file parsed with yaml-cpp, with typed lookups whose errors name the file, the line and the
// key. OpenCV writes YAML files (EuRoC sensor.yaml among them) starting with the line "%YAML:1.0",
// a directive yaml-cpp rejects; that line is blanked before parsing, so yaml-cpp's line numbers
// still match the file.

#include <yaml-cpp/yaml.h>

#include <filesystem>
#include <string>
#include <utility>
#include <vector>

#include "superdyna/core/error.h"

namespace superdyna::io {

class YamlFile {
 public:
  /// Reads and parses `file`. Throws InputError naming the file when it cannot be read, and the
  /// file and line for a syntax error.
  static YamlFile load(const std::filesystem::path& file);

  /// Parses `text` as the content of `file` (which need not exist; it only names errors).
  static YamlFile parse(std::string text, const std::filesystem::path& file);

  const std::filesystem::path& path() const { return file_; }
  const YAML::Node& root() const { return root_; }

  /// Whether the top-level map has `key`.
  bool has(const std::string& key) const;

  /// Child `key` of the map `parent`; throws "missing field" naming `field` (the dotted name used
  /// in messages, e.g. "T_BS.data") when absent, or "expected a map" when `parent` is not one.
  YAML::Node child(const YAML::Node& parent, const std::string& key,
                   const std::string& field) const;
  YAML::Node child(const std::string& key) const { return child(root_, key, key); }

  /// The text of a scalar node; throws unless `node` is a scalar.
  std::string scalar(const YAML::Node& node, const std::string& field) const;
  /// A scalar parsed as a finite number with the strict parsers of text_table.h.
  double number(const YAML::Node& node, const std::string& field) const;
  /// A sequence of finite numbers ("[1, 2, 3]"); throws unless `node` is a sequence.
  std::vector<double> numbers(const YAML::Node& node, const std::string& field) const;

  /// Where `node` is: this file, the node's 1-based line (0 when unknown) and `field`.
  InputLocation at(const YAML::Node& node, const std::string& field) const;

 private:
  YamlFile(std::filesystem::path file, YAML::Node root)
      : file_(std::move(file)), root_(std::move(root)) {}

  std::filesystem::path file_;
  YAML::Node root_;
};

}  // namespace superdyna::io
