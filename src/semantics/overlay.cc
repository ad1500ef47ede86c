#include "superdyna/semantics/overlay.h"

#include <cstdint>
#include <opencv2/imgproc.hpp>

namespace superdyna::semantics {

namespace {

/// A shade of the class colour per instance, so that touching instances stay apart.
cv::Vec3b instanceColour(int id, int class_id) {
  const cv::Scalar base = classColour(class_id);
  const double shade = 0.6 + 0.4 * ((id * 37) % 11) / 10.0;
  return cv::Vec3b(cv::saturate_cast<std::uint8_t>(base[0] * shade),
                   cv::saturate_cast<std::uint8_t>(base[1] * shade),
                   cv::saturate_cast<std::uint8_t>(base[2] * shade));
}

void blendMasks(const cv::Mat& ids, const sensors::InstanceMasks& masks, cv::Mat& canvas) {
  for (int r = 0; r < ids.rows; ++r) {
    const auto* id = ids.ptr<std::uint16_t>(r);
    auto* out = canvas.ptr<cv::Vec3b>(r);
    for (int c = 0; c < ids.cols; ++c) {
      if (id[c] == 0) continue;
      const cv::Vec3b colour = instanceColour(id[c], masks.classOf(id[c]));
      const bool border = (c + 1 < ids.cols && id[c + 1] != id[c]) ||
                          (r + 1 < ids.rows && ids.ptr<std::uint16_t>(r + 1)[c] != id[c]) ||
                          (c > 0 && id[c - 1] != id[c]) ||
                          (r > 0 && ids.ptr<std::uint16_t>(r - 1)[c] != id[c]);
      for (int k = 0; k < 3; ++k)
        out[c][k] = border ? colour[k] : static_cast<std::uint8_t>((out[c][k] + colour[k]) / 2);
    }
  }
}

}  // namespace

cv::Scalar classColour(int class_id) {
  switch (class_id) {
    case sensors::kInstanceClassVehicle:
      return {255, 120, 0};
    case sensors::kInstanceClassPedestrian:
      return {0, 140, 255};
    case sensors::kInstanceClassOtherMovable:
      return {220, 0, 200};
    default:
      return {0, 220, 0};
  }
}

cv::Scalar pointColour(int class_id) {
  switch (class_id) {
    case sensors::kInstanceClassVehicle:
      return {255, 255, 0};
    case sensors::kInstanceClassPedestrian:
      return {60, 60, 255};
    case sensors::kInstanceClassOtherMovable:
      return {255, 255, 255};
    default:
      return {0, 220, 0};
  }
}

cv::Mat drawOverlay(const cv::Mat& image, const cv::Mat& ids, const sensors::InstanceMasks& masks,
                    const std::vector<LabelledPoint>& points) {
  cv::Mat canvas;
  if (image.channels() == 1) {
    cv::cvtColor(image, canvas, cv::COLOR_GRAY2BGR);
  } else {
    canvas = image.clone();
  }
  if (!ids.empty()) blendMasks(ids, masks, canvas);
  for (const LabelledPoint& p : points) {
    const cv::Point centre(cvRound(p.pixel.x), cvRound(p.pixel.y));
    cv::circle(canvas, centre, 3, cv::Scalar(0, 0, 0), cv::FILLED, cv::LINE_AA);
    cv::circle(canvas, centre, 2, p.colour ? *p.colour : pointColour(p.class_id), cv::FILLED,
               cv::LINE_AA);
  }
  return canvas;
}

}  // namespace superdyna::semantics
