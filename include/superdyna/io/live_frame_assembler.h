#pragma once
// Frames from live sensor streams (a ROS node's subscriptions, a driver's callbacks): images and
// IMU samples arrive one message at a time, the two cameras separately and possibly late or out
// of order; the pipeline wants sensors::FrameBundle as a dataset source serves them. The
// assembler pairs left and right images by stamp, holds a frame until the IMU has covered its
// time, gives it the IMU samples since the previous frame (io::bracketingImu, as the folder and
// bag sources do), and counts every message it cannot use instead of stopping. Not thread-safe:
// the caller serialises the calls.

#include <cstddef>
#include <deque>
#include <map>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "superdyna/core/time.h"
#include "superdyna/sensors/frame_bundle.h"
#include "superdyna/sensors/measurements.h"

namespace superdyna::io {

struct LiveAssemblerOptions {
  bool stereo = true;
  bool inertial = true;
  /// Left and right images whose stamps differ by at most this much are one stereo pair (the
  /// pair takes the left stamp).
  TimeNs stereo_tolerance_ns = 3 * kNsPerMillisecond;
  /// A frame waits for the IMU to reach its time until an image this much newer arrives; then it
  /// is dropped (counted in frames_without_imu). An image waits this long for its stereo partner.
  TimeNs max_wait_ns = 500 * kNsPerMillisecond;
};

/// What the assembler could not use, by reason.
struct LiveCounters {
  std::size_t frames = 0;               ///< Frames handed out.
  std::size_t images_out_of_order = 0;  ///< Images stamped at or before a frame handed out.
  std::size_t images_unpaired = 0;      ///< Stereo: images whose partner never came.
  std::size_t imu_out_of_order = 0;     ///< IMU samples stamped at or before the previous one.
  std::size_t frames_without_imu = 0;   ///< Frames the IMU never covered in time.
  std::size_t duplicate_images = 0;     ///< Images of a camera repeating a stamp.
};

/// A frame handed out by the assembler is skipped (the pipeline fell behind): `next`, the frame
/// after it, takes over its IMU samples, so that next's interval starts where the skipped one's
/// did and no motion is lost between the frames the pipeline sees.
void carrySkippedImu(const sensors::FrameBundle& skipped, sensors::FrameBundle& next);

class LiveFrameAssembler {
 public:
  explicit LiveFrameAssembler(const LiveAssemblerOptions& options) : options_(options) {}

  void addImu(const sensors::ImuSample& sample);
  /// `camera` 0 (left / only) or 1 (right); `image` CV_8UC1 (kept as given, not copied).
  void addImage(int camera, TimeNs t_ns, const cv::Mat& image);
  /// The oldest frame that is complete, in time order; nullopt when none is ready yet.
  std::optional<sensors::FrameBundle> next();

  const LiveCounters& counters() const { return counters_; }
  /// Frames complete but not yet taken by next() plus those waiting for the IMU or a partner.
  std::size_t pending() const { return frames_.size(); }

 private:
  struct PendingFrame {
    cv::Mat image0, image1;
  };
  /// Pairs `image` with the other camera's waiting image of a stamp within the tolerance.
  void pairStereo(int camera, TimeNs t_ns, const cv::Mat& image);
  /// Drops unpaired images and frames the IMU has not reached that waited longer than allowed.
  void dropStale();
  bool imuCovers(TimeNs t_ns) const { return !imu_.empty() && imu_.back().t_ns >= t_ns; }

  LiveAssemblerOptions options_;
  LiveCounters counters_;
  std::map<TimeNs, PendingFrame> frames_;  ///< Complete images, by frame stamp.
  std::map<TimeNs, cv::Mat> unpaired_[2];  ///< Stereo images waiting for their partner.
  std::deque<sensors::ImuSample> imu_;     ///< From the last at or before the last frame.
  std::optional<TimeNs> last_frame_t_ns_;  ///< Stamp of the last frame handed out.
  TimeNs newest_image_t_ns_ = 0;
};

}  // namespace superdyna::io
