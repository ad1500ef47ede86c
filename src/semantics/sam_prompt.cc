#include "superdyna/semantics/sam_prompt.h"

#include <algorithm>
#include <array>
#include <cmath>
#include <opencv2/imgproc.hpp>

namespace superdyna::semantics {

namespace {

constexpr std::array<float, 3> kMean = {123.675f, 116.28f, 103.53f};  // R, G, B
constexpr std::array<float, 3> kStd = {58.395f, 57.12f, 57.375f};
constexpr float kLabelOnObject = 1.0f, kLabelOffObject = 0.0f, kLabelPadding = -1.0f;
constexpr float kLabelBoxTopLeft = 2.0f, kLabelBoxBottomRight = 3.0f;

/// JavaScript's Math.round and segment-anything's int(x + 0.5) for the positive sizes here.
int roundHalfUp(double value) {
  return static_cast<int>(std::floor(value + 0.5));
}

void addPoint(SamPrompt& prompt, double x, double y, float label) {
  prompt.coords.push_back(static_cast<float>(x));
  prompt.coords.push_back(static_cast<float>(y));
  prompt.labels.push_back(label);
}

}  // namespace

SamGeometry samGeometryFor(cv::Size image) {
  SamGeometry geometry;
  geometry.image = image;
  geometry.scale = double(kSamInputSide) / std::max(image.width, image.height);
  geometry.scaled = cv::Size(std::min(kSamInputSide, roundHalfUp(image.width * geometry.scale)),
                             std::min(kSamInputSide, roundHalfUp(image.height * geometry.scale)));
  return geometry;
}

std::vector<float> samEncoderInput(const cv::Mat& image, const SamGeometry& geometry) {
  cv::Mat rgb;
  cv::cvtColor(image, rgb, image.channels() == 1 ? cv::COLOR_GRAY2RGB : cv::COLOR_BGR2RGB);
  cv::Mat scaled;
  cv::resize(rgb, scaled, geometry.scaled, 0, 0, cv::INTER_LINEAR);
  constexpr std::size_t kPlane = std::size_t{kSamInputSide} * kSamInputSide;
  std::vector<float> input(3 * kPlane, 0.0f);
  for (int r = 0; r < scaled.rows; ++r) {
    const auto* row = scaled.ptr<cv::Vec3b>(r);
    for (int c = 0; c < scaled.cols; ++c) {
      const std::size_t i = static_cast<std::size_t>(r) * kSamInputSide + c;
      for (int k = 0; k < 3; ++k)
        input[k * kPlane + i] = (row[c][k] - kMean[k]) / kStd[k];
    }
  }
  return input;
}

SamPrompt samBoxPrompt(const cv::Rect2d& box, const SamGeometry& geometry) {
  SamPrompt prompt;
  const double s = geometry.scale;
  addPoint(prompt, box.x * s, box.y * s, kLabelBoxTopLeft);
  addPoint(prompt, (box.x + box.width) * s, (box.y + box.height) * s, kLabelBoxBottomRight);
  return prompt;
}

SamPrompt samPointPrompt(const std::vector<SamPoint>& points, const SamGeometry& geometry) {
  SamPrompt prompt;
  for (const SamPoint& p : points) {
    addPoint(prompt, p.position.x * geometry.scale, p.position.y * geometry.scale,
             p.on_object ? kLabelOnObject : kLabelOffObject);
  }
  addPoint(prompt, 0.0, 0.0, kLabelPadding);
  return prompt;
}

cv::Mat samMask(const float* logits, cv::Size image, double threshold) {
  const cv::Mat view(image, CV_32FC1, const_cast<float*>(logits));
  cv::Mat mask;
  cv::compare(view, threshold, mask, cv::CMP_GT);
  return mask;
}

}  // namespace superdyna::semantics
