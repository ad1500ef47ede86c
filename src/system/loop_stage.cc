#include "superdyna/system/loop_stage.h"

#include <chrono>
#include <utility>

#include "superdyna/core/time.h"

namespace superdyna::system {

namespace {

/// Keyframes that may wait for the loop thread; the next one skips it.
constexpr std::size_t kMaxWaitingKeyFrames = 2;

}  // namespace

LoopStage::LoopStage(const loop::LoopClosingOptions& options, const CameraModel& camera0,
                     const optim::ReprojectionCamera& camera,
                     const mapping::PointFusionOptions& fusion,
                     const optim::PoseOptimizerOptions& pose, bool threaded, bool monocular)
    : closer_(options, camera0, camera, fusion, pose, monocular) {
  if (threaded) worker_ = std::make_unique<MappingWorker>(kMaxWaitingKeyFrames);
}

LoopStage::~LoopStage() {
  stop();
}

bool LoopStage::keyFrameMapped(map::Map& map, map::KeyFrameId id, bool inertial) {
  if (!worker_) {
    loop::LoopStep step = closer_.processKeyFrame(map, id, inertial);
    const bool corrected = step.closure.has_value();
    record(step, inertial);
    return corrected;
  }
  map_ = &map;
  const bool corrected = applyFoundLoop(map);
  if (worker_->unfinished() >= kMaxWaitingKeyFrames) {
    const std::lock_guard lock(mutex_);
    ++summary_.skipped;
    return corrected;
  }
  worker_->submit(
      [this, &map, id, inertial] { record(closer_.findLoop(map, id, inertial), inertial); });
  return corrected;
}

bool LoopStage::applyFoundLoop(map::Map& map) {
  std::optional<loop::VerifiedLoop> found;
  bool inertial = false;
  {
    const std::lock_guard lock(mutex_);
    found = std::exchange(found_, std::nullopt);
    inertial = found_inertial_;
  }
  if (!found) return false;
  const auto start = std::chrono::steady_clock::now();
  std::optional<loop::LoopClosure> closure = closer_.closeLoop(map, *found, inertial);
  const std::lock_guard lock(mutex_);
  summary_.correction_ms += millisecondsSince(start);
  if (!closure) {
    ++summary_.loops_dropped;
    return false;
  }
  countClosure(*closure);
  return true;
}

void LoopStage::record(const loop::LoopStep& step, bool inertial) {
  const std::lock_guard lock(mutex_);
  ++summary_.keyframes;
  summary_.verifications += static_cast<std::size_t>(step.candidates);
  for (int k = 0; k < loop::kRejectionKinds; ++k)
    summary_.rejected[k] += static_cast<std::size_t>(step.rejected[k]);
  summary_.detection_ms += step.detection_ms;
  summary_.verification_ms += step.verification_ms;
  summary_.correction_ms += step.correction_ms;
  if (step.closure) countClosure(*step.closure);
  if (step.found) {
    if (found_) ++summary_.loops_dropped;  // not applied yet: the newer loop replaces it
    found_ = step.found;
    found_inertial_ = inertial;
  }
  summary_.index_descriptors = closer_.database().numDescriptors();
  summary_.index_bytes = closer_.database().indexBytes();
  summary_.index_keyframes = closer_.database().numKeyFrames();
  summary_.index_rebuilds = closer_.database().rebuilds();
}

void LoopStage::countClosure(const loop::LoopClosure& closure) {
  (closure.merge ? summary_.merges : summary_.loops).push_back(closure);
}

void LoopStage::mapReset() {
  if (worker_) worker_->discardPending();  // the loop thread is idle from here on
  {
    const std::lock_guard lock(mutex_);
    found_.reset();
  }
  map_ = nullptr;
  closer_.reset();
}

void LoopStage::finish() {
  if (!worker_) return;
  worker_->finish();
  if (map_ != nullptr) applyFoundLoop(*map_);
}

void LoopStage::stop() {
  worker_.reset();
}

std::vector<map::KeyFrameId> LoopStage::recognizePlace(const tracking::Frame& frame,
                                                       int count) const {
  const cv::Mat rows =
      loop::placeDescriptorRows(frame.features, closer_.options().database.max_descriptors);
  std::vector<map::KeyFrameId> ids;
  for (const loop::PlaceScore& score : closer_.recognize(rows, count))
    ids.push_back(score.id);
  return ids;
}

LoopSummary LoopStage::summary() const {
  const std::lock_guard lock(mutex_);
  return summary_;
}

}  // namespace superdyna::system
