#pragma once
// Error types with context. Library code throws these; the command line turns them into a message
// and a non-zero exit code. Bad input always names the file, and where known the line and field.

#include <filesystem>
#include <stdexcept>
#include <string>
#include <utility>

namespace superdyna {

/// Where in an input file a problem was found. `line` is 1-based; 0 means "whole file".
struct InputLocation {
  InputLocation() = default;
  InputLocation(std::filesystem::path file_path, int line_number = 0, std::string field_name = {})
      : file(std::move(file_path)), line(line_number), field(std::move(field_name)) {}

  std::filesystem::path file;
  int line = 0;
  std::string field;  ///< Column, key or value name; empty when not applicable.

  std::string describe() const;
};

/// Invalid or unreadable user input: a missing file, a malformed row, a bad calibration value.
class InputError : public std::runtime_error {
 public:
  InputError(const InputLocation& where, const std::string& what);
  explicit InputError(const std::string& what);

  const InputLocation& location() const { return where_; }

 private:
  InputLocation where_;
};

/// Invalid option values (out of range, inconsistent); names the option.
class OptionError : public std::invalid_argument {
 public:
  OptionError(const std::string& option, const std::string& what);
};

}  // namespace superdyna
