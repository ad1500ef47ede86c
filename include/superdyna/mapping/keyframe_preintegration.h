#pragma once
// IMU preintegration between temporally consecutive keyframes of the map, built from the samples
// each keyframe stores (KeyFrame::imu_from_previous) and cached across local mapping calls.
//
// The preintegration from keyframe i (the predecessor) to keyframe j is linearised at the bias of
// i (the bias the ImuPreintegrationFactor between them uses). It is re-integrated when the chain
// changed (i was culled, so j's samples now start earlier) or i's bias moved beyond the
// re-integration thresholds; smaller bias changes use the first-order Jacobians.

#include <map>
#include <optional>

#include "superdyna/imu/preintegration.h"
#include "superdyna/map/map.h"

namespace superdyna::mapping {

/// Preintegration of keyframe.imu_from_previous over [t_previous_ns, keyframe.t_ns] at `bias`;
/// nullopt when the samples are missing (fewer than 2) or do not bracket the interval.
std::optional<imu::Preintegration> preintegrateFromPrevious(const map::KeyFrame& keyframe,
                                                            TimeNs t_previous_ns,
                                                            const imu::Bias& bias,
                                                            const imu::ImuNoise& noise);

class KeyFramePreintegrations {
 public:
  explicit KeyFramePreintegrations(const imu::ImuNoise& noise,
                                   const imu::ReintegrationOptions& reintegration = {});

  /// The preintegration from the predecessor of keyframe `id` to `id`, valid for the current map
  /// state; nullptr when `id` has no predecessor or usable samples. The pointer stays valid until
  /// the next call of any non-const member.
  const imu::Preintegration* fromPrevious(const map::Map& map, map::KeyFrameId id);

  /// Forgets keyframes no longer in the map.
  void prune(const map::Map& map);
  void clear() { cache_.clear(); }
  const imu::ImuNoise& noise() const { return noise_; }

 private:
  struct Entry {
    map::KeyFrameId previous = map::kNoKeyFrame;
    imu::Preintegration preintegration;
  };

  imu::ImuNoise noise_;
  imu::ReintegrationOptions reintegration_;
  std::map<map::KeyFrameId, Entry> cache_;
};

}  // namespace superdyna::mapping
