#include "live_colour_segmenter.h"

#include <fmt/format.h>

#include <chrono>

#include "superdyna/core/error.h"

namespace superdyna::ros_node {

namespace {
/// Segmentation images older than the newest frame by this much are dropped unused.
constexpr TimeNs kKeepNs = 2 * kNsPerSecond;
}  // namespace

void LiveColourSegmenter::add(int camera, TimeNs t_ns, const cv::Mat& bgr) {
  {
    const std::lock_guard lock(mutex_);
    std::map<TimeNs, cv::Mat>& images = images_[camera == 0 ? 0 : 1];
    images[t_ns] = bgr;
    while (!images.empty() && images.begin()->first < t_ns - kKeepNs)
      images.erase(images.begin());
  }
  arrived_.notify_all();
}

semantics::Segmentation LiveColourSegmenter::segment(const cv::Mat& image, TimeNs t_ns,
                                                     int camera) {
  std::map<TimeNs, cv::Mat>& images = images_[camera == 0 ? 0 : 1];
  std::unique_lock lock(mutex_);
  const bool found = arrived_.wait_for(lock, std::chrono::nanoseconds(wait_ns_),
                                       [&] { return images.count(t_ns) > 0; });
  if (!found) {
    ++missing_;
    return {cv::Mat::zeros(image.size(), CV_16UC1), {}};
  }
  const cv::Mat colours = images.at(t_ns);
  images.erase(images.begin(), images.upper_bound(t_ns));  // earlier frames are done
  lock.unlock();
  if (colours.size() != image.size()) {
    throw InputError(
        fmt::format("the segmentation image of camera {} at {} ns is {}x{}, the "
                    "camera image {}x{}",
                    camera, t_ns, colours.cols, colours.rows, image.cols, image.rows));
  }
  return semantics::segmentationFromColours(
      colours, tables_.object_of_colour, tables_.classes,
      fmt::format("segmentation topic of camera {} at {} ns", camera, t_ns));
}

std::size_t LiveColourSegmenter::missing() const {
  const std::lock_guard lock(mutex_);
  return missing_;
}

}  // namespace superdyna::ros_node
