#include "dense_output.h"

#include <fmt/format.h>

#include <algorithm>

#include "superdyna/core/error.h"

namespace superdyna::features {

void grayToNetworkInput(const cv::Mat& fitted, int channels, std::vector<float>& input) {
  const int H = fitted.rows, W = fitted.cols;
  const std::size_t plane = static_cast<std::size_t>(H) * W;
  input.resize(plane * static_cast<std::size_t>(channels));
  for (int y = 0; y < H; ++y) {
    const std::uint8_t* src = fitted.ptr<std::uint8_t>(y);
    float* dst = input.data() + static_cast<std::size_t>(y) * W;
    for (int x = 0; x < W; ++x)
      dst[x] = static_cast<float>(src[x]) / 255.0f;
  }
  for (std::size_t c = 1; c < static_cast<std::size_t>(channels); ++c) {
    std::copy(input.begin(), input.begin() + static_cast<std::ptrdiff_t>(plane),
              input.begin() + static_cast<std::ptrdiff_t>(c * plane));
  }
}

DenseMap denseOutputMap(const inference::TensorView& tensor, const std::string& name,
                        cv::Size network_input, const std::filesystem::path& model_file,
                        int stride) {
  const DenseMap map{tensor.data, static_cast<int>(tensor.shape.at(1)),
                     static_cast<int>(tensor.shape.at(2)), static_cast<int>(tensor.shape.at(3))};
  if (map.rows * stride != network_input.height || map.cols * stride != network_input.width) {
    throw InputError(
        InputLocation(model_file),
        fmt::format("output '{}' is {}x{} for a {}x{} input, expected 1/{} of it", name, map.cols,
                    map.rows, network_input.width, network_input.height, stride));
  }
  return map;
}

FeatureSet scoredPixelsToFeatures(const std::vector<ScoredPixel>& points,
                                  const DenseMap& descriptor_map, const ImageFit& fit,
                                  cv::Size image_size, int stride) {
  std::vector<Eigen::Vector2d> pixels;
  pixels.reserve(points.size());
  for (const auto& p : points)
    pixels.emplace_back(p.x, p.y);
  return scoredPixelsToFeatures(points, pixels, descriptor_map, fit, image_size, stride);
}

FeatureSet scoredPixelsToFeatures(const std::vector<ScoredPixel>& points,
                                  const std::vector<Eigen::Vector2d>& pixels,
                                  const DenseMap& descriptor_map, const ImageFit& fit,
                                  cv::Size image_size, int stride) {
  if (pixels.size() != points.size()) {
    throw InputError(fmt::format("scoredPixelsToFeatures: {} pixels for {} points", pixels.size(),
                                 points.size()));
  }
  FeatureSet features;
  features.descriptor_type = DescriptorType::kFloat;
  features.image_size = image_size;
  features.descriptors = sampleDescriptors(descriptor_map, pixels, stride);
  features.keypoints.reserve(points.size());
  const float size = static_cast<float>(stride * fit.pixelScale().x());
  for (std::size_t i = 0; i < points.size(); ++i) {
    Keypoint kp;
    kp.pixel = fit.toOriginal(pixels[i]);
    kp.response = points[i].score;
    kp.size = size;
    features.keypoints.push_back(kp);
  }
  return features;
}

}  // namespace superdyna::features
