#pragma once
// The one wrapper around ONNX Runtime (C++ API, CPU): loads a model file into a session with the
// project's settings, checks it against the signature the caller expects (tensor_spec.h), runs it
// on float tensors and times every run. ONNX Runtime stays behind this header: callers include
// neither its headers nor link it directly.
//
// Errors: a missing or unloadable model file, a model that does not fit the signature and an
// input shape that does not fit it throw InputError naming the model file and the tensor;
// invalid options throw OptionError; a failure inside ONNX Runtime during a run throws InputError
// with ONNX Runtime's message and the input shapes.

#include <cstdint>
#include <filesystem>
#include <initializer_list>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/inference/tensor_spec.h"

namespace superdyna::inference {

/// ONNX Runtime's graph optimisation levels.
enum class GraphOptimization { kDisabled, kBasic, kExtended, kAll };

struct OnnxModelOptions {
  /// Threads of one operator (ONNX Runtime's intra-op pool), >= 1. Runs are deterministic for a
  /// given count.
  int intra_op_threads = 2;
  GraphOptimization optimization = GraphOptimization::kAll;  ///< ORT_ENABLE_ALL by default.
  /// Whether idle intra-op threads spin (lower latency, but they burn CPU that other pipeline
  /// stages could use: XFeat on 752x480 with two threads took twice the CPU time of one thread
  /// when spinning, about the same without). ONNX Runtime's default is to spin; ours is not to.
  bool allow_spinning = false;

  /// Throws OptionError naming the first invalid field.
  void validate() const;
};

/// A read-only view of a dense float32 tensor in row-major (C) order.
struct TensorView {
  const float* data = nullptr;
  std::vector<std::int64_t> shape;
};

/// A dense tensor in row-major (C) order, owning its data as float32: int32 and int64 outputs
/// (a detector's class ids) are converted exactly (run() refuses values beyond 2^24).
struct Tensor {
  std::vector<std::int64_t> shape;
  std::vector<float> data;

  std::int64_t dim(std::size_t i) const { return shape.at(i); }
  /// Pointer to element [index..., 0, ...] of the leading dimensions given.
  const float* at(std::initializer_list<std::int64_t> index) const;
};

/// Product of the dimensions (1 for a scalar); throws InputError for a negative dimension.
std::size_t elementCount(const std::vector<std::int64_t>& shape);

class OnnxModel {
 public:
  /// Loads `file` and checks it against `expected`: every model input must be matched by one
  /// expected input (by name, or by position for unnamed specs) and every expected output must
  /// exist; ranks, fixed dimensions, declared multiples and element types must agree. Throws
  /// InputError ("model file '...' not found" for a missing file; "<file>: output 'desc'
  /// missing; the model has outputs ..." etc.) or OptionError.
  OnnxModel(const std::filesystem::path& file, ModelSignature expected,
            const OnnxModelOptions& options = {});
  /// As above for a network exported in more than one layout (an image input of rank 3 or 4):
  /// the first signature the model fits is signature(); InputError listing each distinct problem
  /// when it fits none.
  OnnxModel(const std::filesystem::path& file, std::vector<ModelSignature> alternatives,
            const OnnxModelOptions& options = {});
  ~OnnxModel();
  OnnxModel(OnnxModel&&) noexcept;
  OnnxModel& operator=(OnnxModel&&) noexcept;
  OnnxModel(const OnnxModel&) = delete;
  OnnxModel& operator=(const OnnxModel&) = delete;

  /// Runs the model: `inputs` in the order of signature().inputs, outputs in the order of
  /// signature().outputs (float32, or int32 / int64 where the signature says so). Input and output
  /// shapes are checked against the signature (InputError naming the tensor). Each call is timed
  /// (lastRunMs(), meanRunMs()).
  std::vector<Tensor> run(const std::vector<TensorView>& inputs);

  /// As run() for a model whose outputs are all float32, without copying them: the views point
  /// into ONNX Runtime's output buffers, which the model keeps until its next run() or
  /// runInPlace() (or its destruction). For networks with large dense outputs: copying ALIKE's
  /// full-resolution descriptor map (94 MB at 768x480) into a freshly allocated buffer per image
  /// (mapped and unmapped by glibc in the pipeline's threads, page-faulted in on every run) made
  /// ALIKE-t take 473 ms per image in the concurrent stereo pipeline, 129 ms without the copy.
  /// InputError for a non-float32 output.
  std::vector<TensorView> runInPlace(const std::vector<TensorView>& inputs);

  /// Runs the model `runs` times on zero-filled inputs of the given shapes without counting the
  /// runs in the timing: ONNX Runtime allocates and plans on the first run of a shape.
  void warmUp(const std::vector<std::vector<std::int64_t>>& input_shapes, int runs = 1);

  const std::filesystem::path& file() const;
  const ModelSignature& signature() const;
  const OnnxModelOptions& options() const;
  /// The inputs and outputs as the model declares them, in the model's order.
  const std::vector<TensorInfo>& modelInputs() const;
  const std::vector<TensorInfo>& modelOutputs() const;
  /// A value of the model's custom metadata (onnx metadata_props), if present.
  std::optional<std::string> metadata(const std::string& key) const;

  /// Duration of the last run() [ms] (0 before the first).
  double lastRunMs() const;
  /// Mean duration of all run() calls [ms] (0 before the first).
  double meanRunMs() const;
  /// Number of timed run() calls.
  int runCount() const;

 private:
  struct Impl;
  std::unique_ptr<Impl> impl_;
};

}  // namespace superdyna::inference
