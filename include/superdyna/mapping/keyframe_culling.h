#pragma once
// Removal of redundant keyframes (ORB-SLAM3 KeyFrameCulling): a keyframe is redundant when at
// least `redundancy` of its map points are seen by at least `min_observers` other keyframes at the
// same or a finer scale (octave <= its own + 1). Candidates are the covisible keyframes of the
// newest one; the first keyframe of the map and the `keep_newest` newest ones are never removed.
//
// With IMU the temporal chain must stay integrable: Map::eraseKeyFrame hands the removed
// keyframe's IMU samples to its successor (so the merged preintegration is that of the
// concatenated samples), and a keyframe is kept when its removal would leave a gap between its
// predecessor and successor longer than max_gap_s (before the inertial initialisation, and for
// the keyframes of the inertial local window) or max_gap_inertial_s (older keyframes, after it),
// or max_gap_old_s for keyframes made more than old_after_s before the newest one. The last tier
// bounds the map of a robot that keeps revisiting a place: with ORB-SLAM3's 3 s rule alone every
// pass leaves a keyframe per ~3 s forever, while the recent trajectory, which the inertial
// estimate of the present rests on, keeps its short gaps.

#include <vector>

#include "superdyna/map/map.h"

namespace superdyna::mapping {

struct KeyFrameCullingOptions {
  bool enabled = true;
  double redundancy = 0.9;  ///< Share of redundant points that makes a keyframe redundant, (0, 1].
  int min_observers = 3;    ///< Other keyframes that must see a point, >= 1.
  int keep_newest = 2;      ///< Newest keyframes never removed, >= 1.
  int max_candidates = 20;  ///< Covisible keyframes examined per call, >= 1.
  double max_gap_s = 0.5;   ///< Largest predecessor-successor gap after a removal [s], > 0.
  /// Same, after the inertial initialisation, for keyframes older than the inertial window [s].
  double max_gap_inertial_s = 3.0;
  /// Same, for keyframes made more than old_after_s before the newest one [s], >=
  /// max_gap_inertial_s.
  double max_gap_old_s = 60.0;
  double old_after_s = 30.0;  ///< [s], > 0.
  void validate() const;
  bool operator==(const KeyFrameCullingOptions&) const = default;
};

/// IMU state of the map as culling needs it.
struct CullingImu {
  bool has_imu = false;  ///< The gap rules apply only with IMU.
  /// After the inertial initialisation: the newest keyframes the inertial local BA optimises
  /// (their gaps stay short); 0 = not initialised.
  int inertial_window = 0;
};

/// Removes the redundant keyframes around `newest` (and the points left without observations)
/// and returns their ids in increasing order.
std::vector<map::KeyFrameId> cullRedundantKeyFrames(map::Map& map, map::KeyFrameId newest,
                                                    const KeyFrameCullingOptions& options,
                                                    const CullingImu& imu = {});

/// The share of the keyframe's map points seen by at least `min_observers` other keyframes at
/// the same or a finer scale (0 when it has no point).
double redundantPointShare(const map::Map& map, map::KeyFrameId id, int min_observers);

}  // namespace superdyna::mapping
