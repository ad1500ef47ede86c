#include "superdyna/system/loop_stage.h"

namespace superdyna::system {

bool LoopStage::keyFrameMapped(map::Map& map, map::KeyFrameId id, bool inertial) {
  const loop::LoopStep step = closer_.processKeyFrame(map, id, inertial);
  const std::lock_guard lock(mutex_);
  ++summary_.keyframes;
  summary_.verifications += static_cast<std::size_t>(step.candidates);
  for (int k = 0; k < loop::kRejectionKinds; ++k)
    summary_.rejected[k] += static_cast<std::size_t>(step.rejected[k]);
  summary_.detection_ms += step.detection_ms;
  summary_.verification_ms += step.verification_ms;
  summary_.correction_ms += step.correction_ms;
  if (step.closure) summary_.loops.push_back(*step.closure);
  summary_.index_descriptors = closer_.database().numDescriptors();
  summary_.index_bytes = closer_.database().descriptorBytes();
  return step.closure.has_value();
}

void LoopStage::mapReset() {
  closer_.reset();
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
