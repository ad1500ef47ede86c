#pragma once
// The loop closer as the tracker's keyframe observer (tracking::KeyFrameObserver), told about each
// keyframe after its local mapping, in the thread that runs the mapping jobs.
//
// - Inline (the deterministic pipeline, bit-identical runs): detection, verification and
//   correction run right there, after each keyframe's local mapping.
// - Threaded (the concurrent pipeline, ORB-SLAM's loop-closing thread): detection and
//   verification, which only read the map, run in a thread of their own, so that local mapping
//   keeps up with the keyframes (at driving speed a keyframe comes every 2-3 frames, and place
//   recognition costs as much as a local BA). A loop verified there is applied where local mapping
//   runs, before the next keyframe's loop step - local mapping is paused while it is corrected,
//   as ORB-SLAM stops it - and, after the last keyframe, by finish(). When keyframes wait for
//   the loop thread, the next keyframe skips it (counted): a keyframe every few frames leaves
//   neighbours enough to recognise the place by.
//
// Counts the loops and times the stages.

#include <cstddef>
#include <memory>
#include <mutex>
#include <optional>
#include <vector>

#include "superdyna/loop/loop_closer.h"
#include "superdyna/system/mapping_worker.h"
#include "superdyna/tracking/tracker.h"

namespace superdyna::system {

/// What loop closing did over a run.
struct LoopSummary {
  std::size_t keyframes = 0;      ///< Keyframes queried.
  std::size_t skipped = 0;        ///< Keyframes the busy loop thread did not take (threaded).
  std::size_t verifications = 0;  ///< Consistent candidates geometrically verified.
  std::size_t rejected[loop::kRejectionKinds] = {};  ///< ... and rejected, by loop::Rejection.
  std::vector<loop::LoopClosure> loops;              ///< Accepted (and corrected) loops.
  /// Atlas maps merged into the active map (loop::LoopClosure::merge), as loops are counted.
  std::vector<loop::LoopClosure> merges;
  std::size_t atlas_maps = 0;  ///< Maps left in the atlas, never merged (at the time of asking).
  std::size_t atlas_keyframes = 0;  ///< ... and their keyframes.
  /// Verified loops and merges not applied (threaded): a keyframe of theirs was culled before
  /// the correction, or a newer loop was found first.
  std::size_t loops_dropped = 0;
  double detection_ms = 0.0;          ///< Summed: database query and consistency check.
  double verification_ms = 0.0;       ///< Summed: matching, RANSAC, guided matching.
  double correction_ms = 0.0;         ///< Summed: pose graph, point correction, fusion.
  std::size_t index_descriptors = 0;  ///< Descriptors in the database at the end.
  std::size_t index_bytes = 0;
  std::size_t index_keyframes = 0;  ///< Keyframes that can receive votes at the end.
  int index_rebuilds = 0;           ///< Rebuilds of the graph index without culled keyframes.
  int global_bas = 0;               ///< Global BAs after loops (mapping.global_ba_iterations) ...
  double global_ba_ms = 0.0;        ///< ... and their summed wall time.
  /// Global BAs solved in their own thread (concurrent) and dropped: a later loop had moved the
  /// map.
  int global_bas_dropped = 0;
};

class LoopStage final : public tracking::KeyFrameObserver {
 public:
  /// The loop closer's arguments (loop::LoopCloser); threaded: detection and verification in a
  /// loop thread (see above).
  LoopStage(const loop::LoopClosingOptions& options, const CameraModel& camera0,
            const optim::ReprojectionCamera& camera, const mapping::PointFusionOptions& fusion,
            const optim::PoseOptimizerOptions& pose, bool threaded = false, bool monocular = false);
  ~LoopStage() override;
  LoopStage(const LoopStage&) = delete;
  LoopStage& operator=(const LoopStage&) = delete;

  /// The maps tracking leaves (loop::LoopCloser::setAtlas); call before the first keyframe.
  void setAtlas(map::Atlas* atlas) { closer_.setAtlas(atlas); }
  bool keyFrameMapped(map::Map& map, map::KeyFrameId id, bool inertial) override;
  /// Threaded: waits for the loop thread's current keyframe, drops the queued ones and a loop
  /// found but not applied.
  void mapReset() override;
  /// The loop closer's keyframe database queried with the frame's place descriptors.
  std::vector<map::KeyFrameId> recognizePlace(const tracking::Frame& frame,
                                              int count) const override;
  /// Threaded, at the end of a run (no mapping job runs any more): the loop thread takes the
  /// keyframes still queued, then a loop found after the last keyframe's mapping is applied to its
  /// map in the calling thread (without the global BA that follows a loop during the run); the
  /// thread ends. Rethrows an error of the loop thread. Nothing to do inline.
  void finish();
  /// Ends the loop thread at once, dropping the queued keyframes (before the map goes).
  void stop();
  /// A copy (thread-safe).
  LoopSummary summary() const;
  /// CPU time of the loop thread so far [ms] (0 inline).
  double cpuMs() const { return worker_ ? worker_->cpuMs() : 0.0; }

 private:
  /// Adds a step's counts and times to the summary; keeps a loop it found for the mapping thread.
  void record(const loop::LoopStep& step, bool inertial);
  /// Counts an applied loop or merge (call with mutex_ held).
  void countClosure(const loop::LoopClosure& closure);
  /// Applies the loop the loop thread found, if any. Returns whether the map was corrected.
  bool applyFoundLoop(map::Map& map);

  loop::LoopCloser closer_;
  std::unique_ptr<MappingWorker> worker_;  ///< The loop thread (threaded only).
  mutable std::mutex mutex_;
  LoopSummary summary_;
  std::optional<loop::VerifiedLoop> found_;  ///< Found by the loop thread, not applied yet.
  bool found_inertial_ = false;
  /// The map of the latest keyframe (threaded: finish() applies a last found loop to it).
  map::Map* map_ = nullptr;
};

}  // namespace superdyna::system
