#pragma once
// The dataset backend's colour format (semantics/dataset_segmenter.h) on live topics: the node
// subscribes to colour segmentation images (VIODE's /cam0/segmentation and /cam1/segmentation,
// or a simulated bag's), and the pipeline's segment() call takes the one of its frame's stamp,
// waiting for it a little when it has not arrived yet. A frame whose segmentation never comes is
// all background (counted), so that a dropped message does not stop the node.

#include <condition_variable>
#include <cstddef>
#include <map>
#include <mutex>
#include <opencv2/core.hpp>
#include <string>

#include "superdyna/core/time.h"
#include "superdyna/semantics/dataset_segmenter.h"
#include "superdyna/semantics/segmenter.h"

namespace superdyna::ros_node {

class LiveColourSegmenter : public semantics::Segmenter {
 public:
  LiveColourSegmenter(semantics::ColourTables tables, TimeNs wait_ns)
      : tables_(std::move(tables)), wait_ns_(wait_ns) {}

  /// A segmentation image (CV_8UC3 BGR) of camera 0 or 1 arrived (callback thread).
  void add(int camera, TimeNs t_ns, const cv::Mat& bgr);
  semantics::Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) override;
  std::string description() const override { return "dataset (live colour segmentation topics)"; }
  bool idsNameObjects() const override { return true; }
  /// Frames segmented as all background because their segmentation image did not come in time.
  std::size_t missing() const;

 private:
  semantics::ColourTables tables_;
  TimeNs wait_ns_;
  mutable std::mutex mutex_;
  std::condition_variable arrived_;
  std::map<TimeNs, cv::Mat> images_[2];
  std::size_t missing_ = 0;
};

}  // namespace superdyna::ros_node
