#include "superdyna/core/error.h"

#include <fmt/format.h>

namespace superdyna {

std::string InputLocation::describe() const {
  std::string out = file.string();
  if (line > 0) out += fmt::format(":{}", line);
  if (!field.empty()) out += fmt::format(" [{}]", field);
  return out;
}

InputError::InputError(const InputLocation& where, const std::string& what)
    : std::runtime_error(fmt::format("{}: {}", where.describe(), what)), where_(where) {}

InputError::InputError(const std::string& what) : std::runtime_error(what) {}

OptionError::OptionError(const std::string& option, const std::string& what)
    : std::invalid_argument(fmt::format("option '{}': {}", option, what)) {}

}  // namespace superdyna
