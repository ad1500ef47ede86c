#include "superdyna/inference/onnx_model.h"

#include <fmt/format.h>
#include <onnxruntime_cxx_api.h>

#include <algorithm>
#include <chrono>
#include <cstring>
#include <system_error>
#include <utility>

#include "superdyna/core/error.h"

namespace superdyna::inference {

namespace fs = std::filesystem;

void OnnxModelOptions::validate() const {
  if (intra_op_threads < 1) {
    throw OptionError("intra_op_threads", fmt::format("must be >= 1, got {}", intra_op_threads));
  }
}

std::size_t elementCount(const std::vector<std::int64_t>& shape) {
  std::size_t count = 1;
  for (const auto d : shape) {
    if (d < 0) throw InputError("tensor shape " + shapeToString(shape) + " has a negative size");
    count *= static_cast<std::size_t>(d);
  }
  return count;
}

const float* Tensor::at(std::initializer_list<std::int64_t> index) const {
  if (index.size() > shape.size()) {
    throw InputError(
        fmt::format("index of rank {} into a tensor of rank {}", index.size(), shape.size()));
  }
  std::size_t offset = 0;
  std::size_t i = 0;
  for (const auto k : index) {
    if (k < 0 || k >= shape[i]) {
      throw InputError(fmt::format("index {} out of range for dimension {} of shape {}", k, i,
                                   shapeToString(shape)));
    }
    offset = offset * static_cast<std::size_t>(shape[i]) + static_cast<std::size_t>(k);
    ++i;
  }
  for (; i < shape.size(); ++i)
    offset *= static_cast<std::size_t>(shape[i]);
  return data.data() + offset;
}

namespace {

ElementType fromOrt(ONNXTensorElementDataType type) {
  switch (type) {
    case ONNX_TENSOR_ELEMENT_DATA_TYPE_FLOAT:
      return ElementType::kFloat32;
    case ONNX_TENSOR_ELEMENT_DATA_TYPE_FLOAT16:
      return ElementType::kFloat16;
    case ONNX_TENSOR_ELEMENT_DATA_TYPE_DOUBLE:
      return ElementType::kFloat64;
    case ONNX_TENSOR_ELEMENT_DATA_TYPE_INT8:
      return ElementType::kInt8;
    case ONNX_TENSOR_ELEMENT_DATA_TYPE_UINT8:
      return ElementType::kUInt8;
    case ONNX_TENSOR_ELEMENT_DATA_TYPE_INT32:
      return ElementType::kInt32;
    case ONNX_TENSOR_ELEMENT_DATA_TYPE_INT64:
      return ElementType::kInt64;
    case ONNX_TENSOR_ELEMENT_DATA_TYPE_BOOL:
      return ElementType::kBool;
    default:
      return ElementType::kOther;
  }
}

GraphOptimizationLevel toOrt(GraphOptimization level) {
  switch (level) {
    case GraphOptimization::kDisabled:
      return ORT_DISABLE_ALL;
    case GraphOptimization::kBasic:
      return ORT_ENABLE_BASIC;
    case GraphOptimization::kExtended:
      return ORT_ENABLE_EXTENDED;
    case GraphOptimization::kAll:
      break;
  }
  return ORT_ENABLE_ALL;
}

TensorInfo describeTensor(const std::string& name, const Ort::TypeInfo& type_info) {
  TensorInfo info;
  info.name = name;
  if (type_info.GetONNXType() != ONNX_TYPE_TENSOR) return info;  // Sequences, maps: kOther.
  const auto tensor = type_info.GetTensorTypeAndShapeInfo();
  info.type = fromOrt(tensor.GetElementType());
  info.dims = tensor.GetShape();
  for (const char* symbolic : tensor.GetSymbolicDimensions()) {
    info.symbolic_dims.emplace_back(symbolic == nullptr ? "" : symbolic);
  }
  info.symbolic_dims.resize(info.dims.size());
  return info;
}

std::string listTensors(const std::vector<TensorInfo>& tensors) {
  std::string out;
  for (const auto& t : tensors)
    out += (out.empty() ? "" : ", ") + t.describe();
  return out.empty() ? "none" : out;
}

/// Index in `model` of the tensor an expected spec refers to (by name, or by position when the
/// spec has no name), or -1.
int findTensor(const TensorSpec& spec, std::size_t position, const std::vector<TensorInfo>& model) {
  if (spec.name.empty()) return position < model.size() ? static_cast<int>(position) : -1;
  for (std::size_t i = 0; i < model.size(); ++i) {
    if (model[i].name == spec.name) return static_cast<int>(i);
  }
  return -1;
}

/// Largest integer magnitude a float holds exactly (2^24).
constexpr std::int64_t kExactFloatInteger = std::int64_t{1} << 24;

/// Integer values as floats; InputError (naming the output) for one a float cannot hold exactly.
template <typename Integer>
std::vector<float> integersAsFloats(const Integer* data, std::size_t count,
                                    const std::string& name) {
  std::vector<float> values(count);
  for (std::size_t k = 0; k < count; ++k) {
    const auto value = static_cast<std::int64_t>(data[k]);
    if (value > kExactFloatInteger || value < -kExactFloatInteger) {
      throw InputError(fmt::format(
          "output '{}' holds {}, beyond the integers a float holds exactly (2^24)", name, value));
    }
    values[k] = static_cast<float>(value);
  }
  return values;
}

/// The elements of an output tensor of `type` (float32, int32 or int64) as floats.
std::vector<float> floatValues(const Ort::Value& value, ElementType type, std::size_t count,
                               const std::string& name) {
  switch (type) {
    case ElementType::kFloat32: {
      const float* data = value.GetTensorData<float>();
      return std::vector<float>(data, data + count);
    }
    case ElementType::kInt32:
      return integersAsFloats(value.GetTensorData<std::int32_t>(), count, name);
    case ElementType::kInt64:
      return integersAsFloats(value.GetTensorData<std::int64_t>(), count, name);
    default:
      throw InputError(
          fmt::format("output '{}' is {}; run() returns float32, int32 and int64 outputs only",
                      name, toString(type)));
  }
}

}  // namespace

struct OnnxModel::Impl {
  fs::path file;
  ModelSignature signature;
  OnnxModelOptions options;
  Ort::Env env{nullptr};
  Ort::Session session{nullptr};
  std::vector<TensorInfo> model_inputs, model_outputs;
  std::vector<std::string> input_names, output_names;  ///< In signature order.
  double last_ms = 0.0;
  double total_ms = 0.0;
  int runs = 0;

  InputError error(const std::string& what) const { return InputError(InputLocation(file), what); }
  /// Adds the last run to the timing (warm-up runs are not counted).
  void countLastRun() {
    total_ms += last_ms;
    ++runs;
  }

  void load();
  /// Takes the first of `alternatives` the model fits; InputError with every distinct problem.
  void checkSignature(const std::vector<ModelSignature>& alternatives);
  /// What keeps the model from fitting the signature (fills input_names/output_names).
  std::optional<std::string> signatureProblem();
  /// The outputs of the last runInPlace(), alive until the next run.
  std::vector<Ort::Value> kept_outputs;

  /// Runs the session on checked inputs; returns the outputs, checked against the signature.
  std::vector<Ort::Value> runSession(const std::vector<TensorView>& inputs);
  std::vector<Tensor> runOnce(const std::vector<TensorView>& inputs);
  std::vector<TensorView> runKeepingOutputs(const std::vector<TensorView>& inputs);
};

void OnnxModel::Impl::load() {
  std::error_code ec;
  if (!fs::is_regular_file(file, ec)) {
    throw InputError(InputLocation(file),
                     fmt::format("model file '{}' not found (looked at {})", file.string(),
                                 fs::absolute(file, ec).string()));
  }
  try {
    env = Ort::Env(ORT_LOGGING_LEVEL_WARNING, "superdyna");
    Ort::SessionOptions session_options;
    session_options.SetIntraOpNumThreads(options.intra_op_threads);
    session_options.SetInterOpNumThreads(1);
    session_options.SetGraphOptimizationLevel(toOrt(options.optimization));
    session_options.SetExecutionMode(ORT_SEQUENTIAL);
    session_options.AddConfigEntry("session.intra_op.allow_spinning",
                                   options.allow_spinning ? "1" : "0");
    session = Ort::Session(env, file.c_str(), session_options);

    Ort::AllocatorWithDefaultOptions allocator;
    for (std::size_t i = 0; i < session.GetInputCount(); ++i) {
      const auto name = session.GetInputNameAllocated(i, allocator);
      model_inputs.push_back(describeTensor(name.get(), session.GetInputTypeInfo(i)));
    }
    for (std::size_t i = 0; i < session.GetOutputCount(); ++i) {
      const auto name = session.GetOutputNameAllocated(i, allocator);
      model_outputs.push_back(describeTensor(name.get(), session.GetOutputTypeInfo(i)));
    }
  } catch (const Ort::Exception& e) {
    throw error(fmt::format("cannot load the ONNX model: {}", e.what()));
  }
}

void OnnxModel::Impl::checkSignature(const std::vector<ModelSignature>& alternatives) {
  std::vector<std::string> problems;
  for (const ModelSignature& candidate : alternatives) {
    signature = candidate;
    input_names.clear();
    output_names.clear();
    const auto problem = signatureProblem();
    if (!problem) return;
    if (std::find(problems.begin(), problems.end(), *problem) == problems.end()) {
      problems.push_back(*problem);
    }
  }
  std::string why;
  for (const std::string& problem : problems)
    why += (why.empty() ? "" : "; or ") + problem;
  throw error(signature.network.empty()
                  ? why
                  : fmt::format("does not fit the {} contract: {}", signature.network, why));
}

std::optional<std::string> OnnxModel::Impl::signatureProblem() {
  const auto& expected = signature;
  if (model_inputs.size() != expected.inputs.size()) {
    return fmt::format("the model has {} input(s) ({}), expected {}: {}", model_inputs.size(),
                       listTensors(model_inputs), expected.inputs.size(),
                       expected.inputs.empty() ? "none" : expected.inputs[0].describe());
  }
  std::vector<bool> used(model_inputs.size(), false);
  for (std::size_t i = 0; i < expected.inputs.size(); ++i) {
    const auto& spec = expected.inputs[i];
    const int index = findTensor(spec, i, model_inputs);
    if (index < 0 || used[static_cast<std::size_t>(index)]) {
      return fmt::format("input '{}' missing; the model has inputs {}", spec.name,
                         listTensors(model_inputs));
    }
    used[static_cast<std::size_t>(index)] = true;
    const auto& actual = model_inputs[static_cast<std::size_t>(index)];
    if (const auto why = mismatch(spec, actual)) {
      return fmt::format("input {}: {} (expected {})", actual.describe(), *why, spec.describe());
    }
    input_names.push_back(actual.name);
  }
  for (std::size_t i = 0; i < expected.outputs.size(); ++i) {
    const auto& spec = expected.outputs[i];
    const int index = findTensor(spec, i, model_outputs);
    if (index < 0) {
      return fmt::format("output '{}' missing; the model has outputs {}", spec.name,
                         listTensors(model_outputs));
    }
    const auto& actual = model_outputs[static_cast<std::size_t>(index)];
    if (const auto why = mismatch(spec, actual)) {
      return fmt::format("output {}: {} (expected {})", actual.describe(), *why, spec.describe());
    }
    output_names.push_back(actual.name);
  }
  return std::nullopt;
}

std::vector<Ort::Value> OnnxModel::Impl::runSession(const std::vector<TensorView>& inputs) {
  if (inputs.size() != signature.inputs.size()) {
    throw error(fmt::format("run() got {} input tensor(s), the model takes {}", inputs.size(),
                            signature.inputs.size()));
  }
  std::string shapes;
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    const auto& spec = signature.inputs[i];
    if (spec.type != ElementType::kFloat32) {
      throw error(fmt::format("input '{}' is {}; run() passes float32 tensors only", input_names[i],
                              toString(spec.type)));
    }
    if (inputs[i].data == nullptr) {
      throw error(fmt::format("input '{}': no data", input_names[i]));
    }
    if (const auto why = shapeMismatch(spec, inputs[i].shape)) {
      throw error(fmt::format("input '{}': {}", input_names[i], *why));
    }
    shapes += (shapes.empty() ? "" : ", ") + input_names[i] + " " + shapeToString(inputs[i].shape);
  }

  const auto memory = Ort::MemoryInfo::CreateCpu(OrtArenaAllocator, OrtMemTypeDefault);
  std::vector<Ort::Value> values;
  std::vector<const char*> in_names, out_names;
  for (std::size_t i = 0; i < inputs.size(); ++i) {
    const auto& shape = inputs[i].shape;
    // ONNX Runtime does not write to input buffers; the C API only lacks a const overload.
    values.push_back(Ort::Value::CreateTensor<float>(memory, const_cast<float*>(inputs[i].data),
                                                     elementCount(shape), shape.data(),
                                                     shape.size()));
    in_names.push_back(input_names[i].c_str());
  }
  for (const auto& name : output_names)
    out_names.push_back(name.c_str());

  std::vector<Ort::Value> results;
  const auto start = std::chrono::steady_clock::now();
  try {
    results = session.Run(Ort::RunOptions{nullptr}, in_names.data(), values.data(), values.size(),
                          out_names.data(), out_names.size());
  } catch (const Ort::Exception& e) {
    throw error(fmt::format("inference failed on {}: {}", shapes, e.what()));
  }
  const auto stop = std::chrono::steady_clock::now();
  last_ms = std::chrono::duration<double, std::milli>(stop - start).count();
  for (std::size_t i = 0; i < results.size(); ++i) {
    const auto info = results[i].GetTensorTypeAndShapeInfo();
    const ElementType type = fromOrt(info.GetElementType());
    if (type != signature.outputs[i].type) {
      throw error(fmt::format("output '{}' is {}, expected {}", output_names[i], toString(type),
                              toString(signature.outputs[i].type)));
    }
    if (const auto why = shapeMismatch(signature.outputs[i], info.GetShape())) {
      throw error(fmt::format("output '{}' for inputs {}: {}", output_names[i], shapes, *why));
    }
  }
  return results;
}

std::vector<Tensor> OnnxModel::Impl::runOnce(const std::vector<TensorView>& inputs) {
  kept_outputs.clear();
  const std::vector<Ort::Value> results = runSession(inputs);
  std::vector<Tensor> outputs;
  for (std::size_t i = 0; i < results.size(); ++i) {
    Tensor tensor;
    tensor.shape = results[i].GetTensorTypeAndShapeInfo().GetShape();
    try {
      tensor.data = floatValues(results[i], signature.outputs[i].type, elementCount(tensor.shape),
                                output_names[i]);
    } catch (const InputError& e) {
      throw error(e.what());
    }
    outputs.push_back(std::move(tensor));
  }
  return outputs;
}

std::vector<TensorView> OnnxModel::Impl::runKeepingOutputs(const std::vector<TensorView>& inputs) {
  for (std::size_t i = 0; i < signature.outputs.size(); ++i) {
    if (signature.outputs[i].type != ElementType::kFloat32) {
      throw error(fmt::format("output '{}' is {}; runInPlace() returns float32 outputs only",
                              output_names[i], toString(signature.outputs[i].type)));
    }
  }
  kept_outputs.clear();  // released before the run, so that ONNX Runtime can reuse their memory
  kept_outputs = runSession(inputs);
  std::vector<TensorView> views;
  for (const auto& value : kept_outputs) {
    views.push_back({value.GetTensorData<float>(), value.GetTensorTypeAndShapeInfo().GetShape()});
  }
  return views;
}

OnnxModel::OnnxModel(const fs::path& file, ModelSignature expected, const OnnxModelOptions& options)
    : OnnxModel(file, std::vector<ModelSignature>{std::move(expected)}, options) {}

OnnxModel::OnnxModel(const fs::path& file, std::vector<ModelSignature> alternatives,
                     const OnnxModelOptions& options)
    : impl_(std::make_unique<Impl>()) {
  options.validate();
  if (alternatives.empty()) throw InputError(InputLocation(file), "no signature to check against");
  impl_->file = file;
  impl_->options = options;
  impl_->load();
  impl_->checkSignature(alternatives);
}

OnnxModel::~OnnxModel() = default;
OnnxModel::OnnxModel(OnnxModel&&) noexcept = default;
OnnxModel& OnnxModel::operator=(OnnxModel&&) noexcept = default;

std::vector<Tensor> OnnxModel::run(const std::vector<TensorView>& inputs) {
  auto outputs = impl_->runOnce(inputs);
  impl_->countLastRun();
  return outputs;
}

std::vector<TensorView> OnnxModel::runInPlace(const std::vector<TensorView>& inputs) {
  auto outputs = impl_->runKeepingOutputs(inputs);
  impl_->countLastRun();
  return outputs;
}

void OnnxModel::warmUp(const std::vector<std::vector<std::int64_t>>& input_shapes, int runs) {
  std::vector<std::vector<float>> buffers;
  std::vector<TensorView> views;
  for (const auto& shape : input_shapes)
    buffers.emplace_back(elementCount(shape), 0.0f);
  for (std::size_t i = 0; i < input_shapes.size(); ++i) {
    views.push_back({buffers[i].data(), input_shapes[i]});
  }
  const double last = impl_->last_ms;
  for (int i = 0; i < runs; ++i)
    impl_->runOnce(views);
  impl_->last_ms = last;
}

const fs::path& OnnxModel::file() const {
  return impl_->file;
}
const ModelSignature& OnnxModel::signature() const {
  return impl_->signature;
}
const OnnxModelOptions& OnnxModel::options() const {
  return impl_->options;
}
const std::vector<TensorInfo>& OnnxModel::modelInputs() const {
  return impl_->model_inputs;
}
const std::vector<TensorInfo>& OnnxModel::modelOutputs() const {
  return impl_->model_outputs;
}

std::optional<std::string> OnnxModel::metadata(const std::string& key) const {
  try {
    Ort::AllocatorWithDefaultOptions allocator;
    const auto meta = impl_->session.GetModelMetadata();
    const auto value = meta.LookupCustomMetadataMapAllocated(key.c_str(), allocator);
    if (!value) return std::nullopt;
    return std::string(value.get());
  } catch (const Ort::Exception& e) {
    throw impl_->error(fmt::format("cannot read metadata '{}': {}", key, e.what()));
  }
}

double OnnxModel::lastRunMs() const {
  return impl_->last_ms;
}
double OnnxModel::meanRunMs() const {
  return impl_->runs == 0 ? 0.0 : impl_->total_ms / impl_->runs;
}
int OnnxModel::runCount() const {
  return impl_->runs;
}

}  // namespace superdyna::inference
