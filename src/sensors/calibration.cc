#include "superdyna/sensors/calibration.h"

namespace superdyna::sensors {

std::string toString(ProjectionModel model) {
  switch (model) {
    case ProjectionModel::kPinhole:
      return "pinhole";
  }
  return "unknown";
}

CameraModel CameraCalibration::cameraModel() const {
  return CameraModel(width, height, fx, fy, cx, cy, distortion_model, distortion);
}

cv::Mat CameraCalibration::cameraMatrix() const {
  return (cv::Mat_<double>(3, 3) << fx, 0.0, cx, 0.0, fy, cy, 0.0, 0.0, 1.0);
}

cv::Mat CameraCalibration::distortionCoefficients() const {
  if (distortion.empty()) return cv::Mat::zeros(1, 4, CV_64F);
  cv::Mat coefficients(1, static_cast<int>(distortion.size()), CV_64F);
  for (std::size_t i = 0; i < distortion.size(); ++i) {
    coefficients.at<double>(0, static_cast<int>(i)) = distortion[i];
  }
  return coefficients;
}

}  // namespace superdyna::sensors
