#include "superdyna/io/live_frame_assembler.h"

#include <iterator>

#include "superdyna/io/dataset_source.h"

namespace superdyna::io {

namespace {
constexpr TimeNs kImuBufferNs = 10 * kNsPerSecond;
}  // namespace

void LiveFrameAssembler::addImu(const sensors::ImuSample& sample) {
  if (!imu_.empty() && sample.t_ns <= imu_.back().t_ns) {
    ++counters_.imu_out_of_order;
    return;
  }
  imu_.push_back(sample);
  // Samples before the last frame handed out and before every waiting image are no longer needed
  // (before the first frame: those older than max_wait_ns); a camera that stopped leaves the last
  // kImuBufferNs.
  TimeNs needed_from = last_frame_t_ns_.value_or(sample.t_ns - options_.max_wait_ns);
  if (!frames_.empty()) needed_from = std::min(needed_from, frames_.begin()->first);
  if (!unpaired_[0].empty()) needed_from = std::min(needed_from, unpaired_[0].begin()->first);
  needed_from = std::max(needed_from, sample.t_ns - kImuBufferNs);
  while (imu_.size() > 1 && imu_[1].t_ns <= needed_from)
    imu_.pop_front();
}

void LiveFrameAssembler::addImage(int camera, TimeNs t_ns, const cv::Mat& image) {
  if (last_frame_t_ns_ && t_ns <= *last_frame_t_ns_) {
    ++counters_.images_out_of_order;
    return;
  }
  newest_image_t_ns_ = std::max(newest_image_t_ns_, t_ns);
  if (options_.stereo) {
    pairStereo(camera, t_ns, image);
  } else if (!frames_.emplace(t_ns, PendingFrame{image, {}}).second) {
    ++counters_.duplicate_images;
  }
  dropStale();
}

void LiveFrameAssembler::pairStereo(int camera, TimeNs t_ns, const cv::Mat& image) {
  std::map<TimeNs, cv::Mat>& others = unpaired_[1 - camera];
  // The other camera's image nearest in time, if within the tolerance.
  auto best = others.end();
  const auto after = others.lower_bound(t_ns);
  for (auto candidate : {after, after == others.begin() ? others.end() : std::prev(after)}) {
    if (candidate == others.end()) continue;
    const TimeNs gap = std::abs(candidate->first - t_ns);
    if (gap <= options_.stereo_tolerance_ns &&
        (best == others.end() || gap < std::abs(best->first - t_ns))) {
      best = candidate;
    }
  }
  if (best == others.end()) {
    if (!unpaired_[camera].emplace(t_ns, image).second) ++counters_.duplicate_images;
    return;
  }
  const TimeNs left_t_ns = camera == 0 ? t_ns : best->first;
  PendingFrame frame =
      camera == 0 ? PendingFrame{image, best->second} : PendingFrame{best->second, image};
  others.erase(best);
  if (!frames_.emplace(left_t_ns, std::move(frame)).second) ++counters_.duplicate_images;
}

void LiveFrameAssembler::dropStale() {
  const TimeNs oldest_kept = newest_image_t_ns_ - options_.max_wait_ns;
  for (std::map<TimeNs, cv::Mat>& images : unpaired_) {
    while (!images.empty() && images.begin()->first < oldest_kept) {
      images.erase(images.begin());
      ++counters_.images_unpaired;
    }
  }
  if (!options_.inertial) return;
  // Frames the IMU covers are ready (the oldest ones); the others wait at most max_wait_ns.
  for (auto frame = frames_.begin(); frame != frames_.end() && frame->first < oldest_kept;) {
    if (imuCovers(frame->first)) {
      ++frame;
      continue;
    }
    frame = frames_.erase(frame);
    ++counters_.frames_without_imu;
  }
}

std::optional<sensors::FrameBundle> LiveFrameAssembler::next() {
  if (frames_.empty()) return std::nullopt;
  const auto oldest = frames_.begin();
  if (options_.inertial && !imuCovers(oldest->first)) return std::nullopt;
  sensors::FrameBundle bundle;
  bundle.index = counters_.frames++;
  bundle.t_ns = oldest->first;
  bundle.image0 = oldest->second.image0;
  bundle.image1 = oldest->second.image1;
  frames_.erase(oldest);
  if (options_.inertial) {
    const std::vector<sensors::ImuSample> imu(imu_.begin(), imu_.end());
    bundle.imu = bracketingImu(imu, last_frame_t_ns_.value_or(bundle.t_ns), bundle.t_ns);
    // Keep the samples from the last one at or before this frame on: the next interval's start.
    while (imu_.size() > 1 && imu_[1].t_ns <= bundle.t_ns)
      imu_.pop_front();
  }
  last_frame_t_ns_ = bundle.t_ns;
  // Unpaired images older than this frame can no longer make a frame.
  for (std::map<TimeNs, cv::Mat>& images : unpaired_) {
    while (!images.empty() && images.begin()->first <= bundle.t_ns) {
      images.erase(images.begin());
      ++counters_.images_unpaired;
    }
  }
  return bundle;
}

void carrySkippedImu(const sensors::FrameBundle& skipped, sensors::FrameBundle& next) {
  if (skipped.imu.empty()) return;
  std::vector<sensors::ImuSample> merged = skipped.imu;
  for (const sensors::ImuSample& sample : next.imu)
    if (sample.t_ns > merged.back().t_ns) merged.push_back(sample);
  next.imu = std::move(merged);
}

}  // namespace superdyna::io
