#include "dense_output.h"

#include <fmt/format.h>

#include "superdyna/core/error.h"

namespace superdyna::features {

DenseMap denseOutputMap(const inference::Tensor& tensor, const std::string& name,
                        cv::Size network_input, const std::filesystem::path& model_file,
                        int stride) {
  const DenseMap map{tensor.data.data(), static_cast<int>(tensor.dim(1)),
                     static_cast<int>(tensor.dim(2)), static_cast<int>(tensor.dim(3))};
  if (map.rows * stride != network_input.height || map.cols * stride != network_input.width) {
    throw InputError(
        InputLocation(model_file),
        fmt::format("output '{}' is {}x{} for a {}x{} input, expected 1/{} of it", name, map.cols,
                    map.rows, network_input.width, network_input.height, stride));
  }
  return map;
}

}  // namespace superdyna::features
