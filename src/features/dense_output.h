#pragma once
// Private to the learned extractors: viewing a network's NCHW output as a DenseMap, checked to be
// at the expected stride of the network input.

#include <filesystem>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/features/feature_set.h"
#include "superdyna/features/keypoint_decoding.h"
#include "superdyna/inference/onnx_model.h"

namespace superdyna::features {

/// The 8-bit image `fitted` (network-input size) scaled to [0, 1] as a [1, channels, H, W] input:
/// the gray image in every channel. `input` is resized to hold it.
void grayToNetworkInput(const cv::Mat& fitted, int channels, std::vector<float>& input);

/// A view of batch item 0 of `tensor` (NCHW); throws InputError naming `model_file` and the output
/// when its spatial size is not the network input's divided by `stride`.
DenseMap denseOutputMap(const inference::TensorView& tensor, const std::string& name,
                        cv::Size network_input, const std::filesystem::path& model_file,
                        int stride);

/// The keypoints (in the original image's pixels, score as response) and their descriptors
/// sampled from `descriptor_map` at stride `stride` of the network input, as one FeatureSet.
FeatureSet scoredPixelsToFeatures(const std::vector<ScoredPixel>& points,
                                  const DenseMap& descriptor_map, const ImageFit& fit,
                                  cv::Size image_size, int stride);
/// The same with the keypoints at `pixels` (network-input pixels, one per point, e.g. refined
/// to sub-pixel positions) instead of the points' integer pixels.
FeatureSet scoredPixelsToFeatures(const std::vector<ScoredPixel>& points,
                                  const std::vector<Eigen::Vector2d>& pixels,
                                  const DenseMap& descriptor_map, const ImageFit& fit,
                                  cv::Size image_size, int stride);

}  // namespace superdyna::features
