#include "superdyna/inference/tensor_spec.h"

#include <fmt/format.h>

#include <utility>

namespace superdyna::inference {

std::string toString(ElementType type) {
  switch (type) {
    case ElementType::kFloat32:
      return "float32";
    case ElementType::kFloat16:
      return "float16";
    case ElementType::kFloat64:
      return "float64";
    case ElementType::kInt8:
      return "int8";
    case ElementType::kUInt8:
      return "uint8";
    case ElementType::kInt32:
      return "int32";
    case ElementType::kInt64:
      return "int64";
    case ElementType::kBool:
      return "bool";
    case ElementType::kOther:
      break;
  }
  return "other";
}

DimSpec DimSpec::fixed(std::int64_t value, std::string what) {
  return DimSpec{value, 1, std::move(what)};
}

DimSpec DimSpec::dynamic(std::string what) {
  return DimSpec{-1, 1, std::move(what)};
}

DimSpec DimSpec::multipleOf(std::int64_t multiple_of, std::string what) {
  return DimSpec{-1, multiple_of, std::move(what)};
}

bool DimSpec::accepts(std::int64_t value) const {
  if (isFixed()) return value == size;
  return value > 0 && (multiple <= 1 || value % multiple == 0);
}

std::string DimSpec::describe() const {
  if (isFixed()) return std::to_string(size);
  if (multiple > 1) return fmt::format("a multiple of {}", multiple);
  return "any";
}

namespace {

std::string dimName(const DimSpec& dim, std::size_t index) {
  return dim.label.empty() ? fmt::format("dimension {}", index)
                           : fmt::format("dimension {} ({})", index, dim.label);
}

std::string joined(const std::vector<std::string>& parts) {
  std::string out;
  for (std::size_t i = 0; i < parts.size(); ++i) {
    if (i > 0) out += ", ";
    out += parts[i];
  }
  return out;
}

}  // namespace

std::string TensorSpec::describe() const {
  std::vector<std::string> parts;
  for (const auto& dim : dims) {
    parts.push_back(dim.isFixed()      ? std::to_string(dim.size)
                    : dim.multiple > 1 ? fmt::format("{}*k", dim.multiple)
                                       : std::string(dim.label.empty() ? "any" : dim.label));
  }
  return fmt::format("'{}' [{}] {}", name.empty() ? "(any name)" : name, joined(parts),
                     toString(type));
}

std::string TensorInfo::describe() const {
  std::vector<std::string> parts;
  for (std::size_t i = 0; i < dims.size(); ++i) {
    if (dims[i] >= 0) {
      parts.push_back(std::to_string(dims[i]));
    } else if (i < symbolic_dims.size() && !symbolic_dims[i].empty()) {
      parts.push_back(symbolic_dims[i]);
    } else {
      parts.push_back("?");
    }
  }
  return fmt::format("'{}' [{}] {}", name, joined(parts), toString(type));
}

std::optional<std::string> mismatch(const TensorSpec& expected, const TensorInfo& actual) {
  if (actual.type != expected.type) {
    return fmt::format("element type is {}, expected {}", toString(actual.type),
                       toString(expected.type));
  }
  if (actual.dims.size() != expected.dims.size()) {
    return fmt::format("rank is {} ({}), expected {} ({})", actual.dims.size(), actual.describe(),
                       expected.dims.size(), expected.describe());
  }
  for (std::size_t i = 0; i < expected.dims.size(); ++i) {
    const std::int64_t declared = actual.dims[i];
    if (declared < 0) continue;  // Dynamic in the model: checked on every run.
    if (!expected.dims[i].accepts(declared)) {
      return fmt::format("{} is {}, expected {}", dimName(expected.dims[i], i), declared,
                         expected.dims[i].describe());
    }
  }
  return std::nullopt;
}

std::optional<std::string> shapeMismatch(const TensorSpec& expected,
                                         const std::vector<std::int64_t>& shape) {
  if (shape.size() != expected.dims.size()) {
    return fmt::format("shape {} has rank {}, expected {}", shapeToString(shape), shape.size(),
                       expected.dims.size());
  }
  for (std::size_t i = 0; i < shape.size(); ++i) {
    if (!expected.dims[i].accepts(shape[i])) {
      return fmt::format("shape {}: {} is {}, expected {}", shapeToString(shape),
                         dimName(expected.dims[i], i), shape[i], expected.dims[i].describe());
    }
  }
  return std::nullopt;
}

std::string shapeToString(const std::vector<std::int64_t>& shape) {
  std::vector<std::string> parts;
  for (const auto d : shape)
    parts.push_back(std::to_string(d));
  return fmt::format("[{}]", joined(parts));
}

}  // namespace superdyna::inference
