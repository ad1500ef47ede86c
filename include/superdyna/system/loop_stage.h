#pragma once
// The loop closer as the tracker's keyframe observer (tracking::KeyFrameObserver): it runs where
// local mapping runs, after each keyframe's local mapping - inline in the deterministic pipeline
// (bit-identical runs), in the mapping thread of the concurrent one, so that local mapping is
// paused while a loop is corrected and tracking never waits for it (only, as for local BA, when
// the mapping queue is full). Counts the loops and times the stages.

#include <cstddef>
#include <mutex>
#include <vector>

#include "superdyna/loop/loop_closer.h"
#include "superdyna/tracking/tracker.h"

namespace superdyna::system {

/// What loop closing did over a run.
struct LoopSummary {
  std::size_t keyframes = 0;      ///< Keyframes queried.
  std::size_t verifications = 0;  ///< Consistent candidates geometrically verified.
  std::size_t rejected[loop::kRejectionKinds] = {};  ///< ... and rejected, by loop::Rejection.
  std::vector<loop::LoopClosure> loops;              ///< Accepted (and corrected) loops.
  double detection_ms = 0.0;          ///< Summed: database query and consistency check.
  double verification_ms = 0.0;       ///< Summed: matching, RANSAC, guided matching.
  double correction_ms = 0.0;         ///< Summed: pose graph, point correction, fusion.
  std::size_t index_descriptors = 0;  ///< Descriptors in the database at the end.
  std::size_t index_bytes = 0;
};

class LoopStage final : public tracking::KeyFrameObserver {
 public:
  /// The loop closer's arguments (loop::LoopCloser).
  LoopStage(const loop::LoopClosingOptions& options, const CameraModel& camera0,
            const optim::ReprojectionCamera& camera, const mapping::PointFusionOptions& fusion,
            const optim::PoseOptimizerOptions& pose)
      : closer_(options, camera0, camera, fusion, pose) {}

  bool keyFrameMapped(map::Map& map, map::KeyFrameId id, bool inertial) override;
  void mapReset() override;
  /// The loop closer's keyframe database queried with the frame's place descriptors.
  std::vector<map::KeyFrameId> recognizePlace(const tracking::Frame& frame,
                                              int count) const override;
  /// A copy (thread-safe).
  LoopSummary summary() const;

 private:
  loop::LoopCloser closer_;
  mutable std::mutex mutex_;
  LoopSummary summary_;
};

}  // namespace superdyna::system
