#pragma once
// What a network is expected to look like: the names, ranks, dimensions and element types of its
// input and output tensors. OnnxModel checks a model file against such a signature when it is
// loaded and checks every input and output against it at run time, so that a wrong model (a
// detector given as a keypoint network, a colour model given as a grayscale one) fails at once
// with a message naming the model file and the tensor, not deep inside the decoding.

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

namespace superdyna::inference {

/// Element type of a tensor (the subset of ONNX types the project meets; others are kOther).
enum class ElementType {
  kFloat32,
  kFloat16,
  kFloat64,
  kInt8,
  kUInt8,
  kInt32,
  kInt64,
  kBool,
  kOther
};
std::string toString(ElementType type);

/// One expected dimension: a fixed size, or dynamic (any size, optionally a multiple of some
/// number, e.g. image sides that must be multiples of 32).
struct DimSpec {
  std::int64_t size = -1;     ///< Required size, or -1 for dynamic.
  std::int64_t multiple = 1;  ///< A dynamic size must be a positive multiple of this (>= 1).
  std::string label;          ///< For messages: "channels", "height", ...

  static DimSpec fixed(std::int64_t value, std::string what = {});
  static DimSpec dynamic(std::string what = {});
  static DimSpec multipleOf(std::int64_t multiple_of, std::string what = {});

  bool isFixed() const { return size >= 0; }
  /// Whether a concrete size satisfies this dimension.
  bool accepts(std::int64_t value) const;
  /// "3", "any", "a multiple of 32".
  std::string describe() const;
};

/// One expected tensor. An empty name matches the model's tensor at the same position (for
/// inputs whose name differs between exporters); otherwise the name must match exactly.
struct TensorSpec {
  std::string name;
  std::vector<DimSpec> dims;  ///< Rank = dims.size().
  ElementType type = ElementType::kFloat32;

  /// "'semi' [any, 65, any, any] float32".
  std::string describe() const;
};

/// The expected inputs (all of the model's inputs, in the order run() takes them) and the outputs
/// the caller reads (a subset of the model's outputs, in the order run() returns them).
struct ModelSignature {
  std::vector<TensorSpec> inputs;
  std::vector<TensorSpec> outputs;
  /// The kind of network, for messages ("XFeat": "... does not fit the XFeat contract: ...").
  std::string network;
};

/// A tensor as a model declares it: dims are -1 where dynamic (symbolic names kept).
struct TensorInfo {
  std::string name;
  std::vector<std::int64_t> dims;
  std::vector<std::string> symbolic_dims;  ///< Same length as dims; "" where none is given.
  ElementType type = ElementType::kOther;

  /// "'input' [batch, 3, height, width] float32".
  std::string describe() const;
};

/// Why `actual` does not fit `expected` as declared by a model (a declared dynamic dimension fits
/// every DimSpec; it is checked at run time), or nullopt when it fits. The reason names the
/// dimension: "dimension 1 (channels) is 3, expected 1".
std::optional<std::string> mismatch(const TensorSpec& expected, const TensorInfo& actual);

/// Why a concrete shape does not fit `expected`, or nullopt when it fits.
std::optional<std::string> shapeMismatch(const TensorSpec& expected,
                                         const std::vector<std::int64_t>& shape);

/// "[1, 3, 480, 768]".
std::string shapeToString(const std::vector<std::int64_t>& shape);

}  // namespace superdyna::inference
