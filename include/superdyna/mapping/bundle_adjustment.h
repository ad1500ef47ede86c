#pragma once
// Bundle adjustment of a set of keyframes and the map points they observe (Ceres), visual or
// visual-inertial, shared by the local BA and the full BA after the inertial initialisation.
//
// Visual: reprojection factors (Huber, left camera and, unrectified, right camera) on the poses of
// the optimised keyframes and the points they observe; the fixed keyframes (given, or found as
// observers of those points) only add their observations of them.
// Visual-inertial (ORB-SLAM3 local inertial BA): every optimised keyframe also has velocity and
// bias blocks; an ImuPreintegrationFactor and a BiasRandomWalkFactor join it to its temporal
// predecessor when that is optimised or fixed (a fixed predecessor anchors the window with its
// pose, velocity and biases held). The pose blocks then hold the IMU poses T_w_i = T_w_b T_b_i and
// the cameras are re-expressed in the IMU frame, so that body and IMU may differ.
// Reprojections that cannot be evaluated at the initial state (point behind the camera) stay out
// of the problem, since Ceres would abandon the whole solve; points left with fewer than 2
// residuals are not optimised.
// After solving: poses (and inertial states) and points are written back, left observations
// failing the chi^2 test or left out as above are removed and the points' normals and distances
// are updated. When Ceres gives no usable solution, a warning is logged and nothing is written.
// The state is read and solved without a lock; everything written afterwards is one map update
// (Map::updateLock()), so the caller must not hold the map's read or update lock.

#include <atomic>
#include <map>
#include <memory>
#include <optional>
#include <vector>

#include "superdyna/imu/preintegration.h"
#include "superdyna/map/map.h"
#include "superdyna/mapping/keyframe_preintegration.h"
#include "superdyna/optim/reprojection_factor.h"

namespace superdyna::mapping {

/// Right-camera observations of one keyframe's keypoints (unrectified stereo), by keypoint index.
using RightObservations = std::vector<std::optional<Eigen::Vector2d>>;

struct BundleAdjustmentSettings {
  int iterations = 10;                       ///< Levenberg-Marquardt iterations.
  double chi2_outlier = optim::kChi2Mono95;  ///< Huber threshold and outlier test.
  double sigma0_px = 1.0;                    ///< Keypoint std at octave 0 [px].
  double scale_factor = 1.2;                 ///< Pyramid scale between octaves.
};

/// What is optimised.
struct BundleAdjustmentWindow {
  std::vector<map::KeyFrameId> optimised;  ///< Pose (and inertial state) free.
  std::vector<map::KeyFrameId> fixed;      ///< Held; observations and IMU anchor only.
  /// An optimised keyframe whose pose carries the gauge (kNoKeyFrame = none): visual, its pose is
  /// held; visual-inertial, only its yaw and position are (roll and pitch are observable through
  /// gravity), and its velocity and biases stay free.
  map::KeyFrameId gauge = map::kNoKeyFrame;
  /// Up to this many keyframes outside `optimised` and `fixed` that observe the optimised
  /// keyframes' points join as fixed keyframes with their observations of those points (ORB-SLAM's
  /// local BA), most shared points first (ties: older first); 0 = none.
  int fixed_observers = 0;
  /// When fewer keyframes than this end up fixed (given and observers), the oldest optimised
  /// keyframes are held too: 1 fixes the 6-DoF gauge of a metric (stereo) map; a monocular map
  /// needs 2, since one fixed pose leaves the scale free.
  int min_fixed = 0;
  /// Visual-inertial: needs `imu` in the context.
  bool inertial = false;
  /// Visual-inertial: a fixed keyframe before an optimised one (the window's anchor) keeps its
  /// pose and biases held, and its velocity too unless the preintegration to that keyframe spans
  /// less than this [s] (0 = always held). Held, its velocity is an estimate from an earlier
  /// window imposed as exact: with keyframes a frame or two apart the window is a fraction of a
  /// second long, follows that velocity rather than its observations, and hands the error on
  /// from window to window. Over longer gaps the held velocity is the better estimate.
  double free_anchor_velocity_below_s = 0.0;
  /// Visual-inertial: zero-mean Gaussian prior on the biases of the oldest optimised keyframe,
  /// [rad/s] and [m/s^2] (the prior of the inertial initialisation, so that a full BA after it
  /// counts that information once); 0 = none.
  double bias_prior_sigma_gyro = 0.0;
  double bias_prior_sigma_acc = 0.0;
};

/// IMU side of the problem.
struct BundleAdjustmentImu {
  SE3d T_b_i;                                          ///< IMU pose in the body frame.
  KeyFramePreintegrations* preintegrations = nullptr;  ///< Cache (not null).
};

struct BundleAdjustmentResult {
  int observations = 0;  ///< Reprojection residuals.
  int imu_edges = 0;     ///< Preintegration factors.
  int outliers = 0;      ///< Observations removed (chi^2 test or behind the camera at the start).
};

/// The full visual-inertial BA after an inertial (re-)initialisation: every keyframe of `ids`
/// (oldest first) optimised, the gauge on the oldest (yaw and position held; its roll, pitch,
/// velocity and biases estimated), and the initialisation's zero-mean bias prior [rad/s], [m/s^2].
BundleAdjustmentWindow fullInertialWindow(const std::vector<map::KeyFrameId>& ids,
                                          double bias_prior_sigma_gyro,
                                          double bias_prior_sigma_acc);

/// Runs the BA on the map. `cameras`: [0] left, [1] right (optional), in the body frame;
/// `right`: right observations by keyframe (missing = none). Keyframes that are not in the map
/// are skipped. Deterministic (single-threaded, ordered containers).
BundleAdjustmentResult bundleAdjust(map::Map& map, const BundleAdjustmentWindow& window,
                                    const std::vector<optim::ReprojectionCamera>& cameras,
                                    const std::map<map::KeyFrameId, RightObservations>& right,
                                    const BundleAdjustmentSettings& settings,
                                    const std::optional<BundleAdjustmentImu>& imu = std::nullopt);

namespace detail {
class Problem;
}

/// bundleAdjust() in three steps, so that its solve runs away from the map (the global BA in a
/// thread of its own, ORB-SLAM3's): the constructor loads the state under the map's read lock,
/// solve() touches no map and may run in any thread, apply() writes the solution into the map as
/// it is by then, one map update: solved keyframes and points take their solution, keyframes
/// added meanwhile move with their temporal predecessor's correction (velocities rotated with
/// it), points left out of the solve with their oldest observer's, outliers still observed are
/// removed; every keyframe's correction is recorded (map::Map::recordCorrection), so poses held
/// outside the map follow. The object keeps a reference to the map: it must not outlive it.
class DeferredBundleAdjustment {
 public:
  /// As bundleAdjust(); the caller holds neither of the map's locks. `right` and the IMU's
  /// preintegration cache are used here only.
  DeferredBundleAdjustment(map::Map& map, const BundleAdjustmentWindow& window,
                           const std::vector<optim::ReprojectionCamera>& cameras,
                           const std::map<map::KeyFrameId, RightObservations>& right,
                           const BundleAdjustmentSettings& settings,
                           const std::optional<BundleAdjustmentImu>& imu = std::nullopt);
  ~DeferredBundleAdjustment();
  DeferredBundleAdjustment(const DeferredBundleAdjustment&) = delete;
  DeferredBundleAdjustment& operator=(const DeferredBundleAdjustment&) = delete;

  void solve();
  /// Makes a solve() running in another thread stop at its next iteration; apply() then leaves
  /// the map unchanged but for the observations that were behind a camera at the start.
  void abort() { abort_ = true; }
  /// Call after solve() returned, where the map's updates are made; the caller holds neither lock.
  BundleAdjustmentResult apply();
  /// The map's correction count (map::Map::correctionCount) when the state was loaded: a solution
  /// older than a correction made since (a loop closure) must not be applied.
  int generation() const { return generation_; }

 private:
  std::unique_ptr<detail::Problem> problem_;
  int generation_ = 0;
  std::atomic<bool> abort_ = false;
};

}  // namespace superdyna::mapping
