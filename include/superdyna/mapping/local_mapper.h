#pragma once
// Local mapping, run sequentially after each new keyframe.
//
// New points (triangulation between keyframes, when on) are followed by the fusion of duplicated
// points with the neighbours' (point_fusion.h). Then, visual (stereo or mono, or with IMU before
// the inertial initialisation): local bundle
// adjustment with Ceres over the newest keyframe and its best covisible keyframes; keyframes
// outside the window that observe its points add their observations with fixed poses (the gauge,
// as in ORB-SLAM; the map's first keyframe is held too).
// With IMU: once the map holds enough keyframes over a long enough time, the inertial
// initialisation (inertial_map_initializer.h) aligns the map with gravity and estimates velocities
// and biases (monocular rigs: the map scale too), followed by a full visual-inertial BA; it is
// refined (initialisation with relaxed bias priors + full BA) when the map is refine_first_s and
// refine_second_s old. From then on the local BA is visual-inertial (ORB-SLAM3): the newest
// inertial_window_keyframes keyframes of the temporal chain are optimised (pose, velocity, biases)
// with preintegration and bias random walk factors between consecutive ones; the keyframe before
// them is fixed with its biases, and with its velocity unless it is less than
// inertial_free_anchor_velocity_below_s before the window; up to inertial_fixed_covisible
// keyframes outside the window that observe its points add their observations with fixed poses.
// Then: removal of outlier observations, culling of recent map points that too few keyframes
// observe, and culling of redundant keyframes (keyframe_culling.h).

#include <Eigen/Core>
#include <map>
#include <memory>
#include <optional>
#include <utility>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/geometry.h"
#include "superdyna/core/task_thread.h"
#include "superdyna/map/map.h"
#include "superdyna/mapping/bundle_adjustment.h"
#include "superdyna/mapping/inertial_map_initializer.h"
#include "superdyna/mapping/keyframe_culling.h"
#include "superdyna/mapping/keyframe_preintegration.h"
#include "superdyna/mapping/point_fusion.h"
#include "superdyna/mapping/point_triangulator.h"
#include "superdyna/optim/reprojection_factor.h"
#include "superdyna/sensors/calibration.h"

namespace superdyna::mapping {

struct LocalMapperOptions {
  /// Keyframes optimised together (the newest and its best covisible ones), >= 2.
  int window_keyframes = 8;
  /// Keyframes outside the window observing its points, held fixed with their observations
  /// (most shared points first), >= 0. They carry the gauge; without any, the oldest window
  /// keyframe is held instead.
  int fixed_observer_keyframes = 20;
  int iterations = 10;                       ///< Levenberg-Marquardt iterations per local BA, >= 1.
  double chi2_outlier = optim::kChi2Mono95;  ///< Observations above are removed after BA.
  int cull_after_keyframes = 3;   ///< Age (in keyframes) at which new points are checked, >= 1.
  int min_observations = 2;       ///< Keyframes a checked point must be seen by, >= 1.
  double min_found_ratio = 0.25;  ///< Matched / visible ratio a checked point needs, [0, 1].
  double sigma0_px = 1.0;         ///< Keypoint standard deviation at octave 0 [px], > 0.
  double scale_factor = 1.2;      ///< Pyramid scale between octaves, > 1.
  /// Triangulate new points between each new keyframe and its neighbours before the BA (the only
  /// source of new points in monocular maps). Its sigma0_px and scale_factor are the ones above.
  bool triangulate = false;
  PointTriangulatorOptions triangulation;
  /// Fusion of duplicated points with the neighbours' after the new points, before the BA. Its
  /// sigma0_px is the one above.
  PointFusionOptions fusion;
  KeyFrameCullingOptions keyframe_culling;  ///< Redundant keyframe removal.

  // ---- With IMU ----
  bool inertial = true;                  ///< Run the inertial initialisation and VI BA (with IMU).
  InertialMapInitOptions inertial_init;  ///< First initialisation (scale: estimated for mono).
  double refine_first_s = 5.0;           ///< Map age of the first refinement [s], > 0 (0 = none).
  double refine_second_s = 15.0;         ///< ... of the second, > refine_first_s (0 = none).
  int full_ba_iterations = 20;  ///< Iterations of the full VI BA after an initialisation, >= 1.
  int inertial_window_keyframes = 10;  ///< Temporal keyframes optimised by the VI local BA, >= 2.
  /// Keyframes outside the VI window observing its points, held fixed with their observations
  /// (most shared points first), >= 0.
  int inertial_fixed_covisible = 5;
  int inertial_iterations = 5;  ///< Iterations of the VI local BA, >= 1.
  /// The VI window's anchor (the fixed keyframe before it) keeps its velocity free when it is less
  /// than this before the window's first keyframe [s], >= 0 (0 = always held): a held one carries
  /// an old estimate into every window of a dense keyframe chain (bundle_adjustment.h).
  double inertial_free_anchor_velocity_below_s = 0.0;

  /// Iterations of the global BA after a loop correction, >= 0 (0 = none): every keyframe of
  /// the map optimised with its points, the map's first keyframe carrying the gauge (fixed pose;
  /// inertial maps: the full VI BA, its yaw and position held).
  int global_ba_iterations = 0;
  void validate() const;
  bool operator==(const LocalMapperOptions&) const = default;
};

/// What one processKeyFrame() call did.
struct LocalMappingResult {
  int observations = 0;  ///< Reprojection residuals of the BA.
  int imu_edges = 0;     ///< Preintegration factors of the BA.
  /// Set when the map was moved (gravity alignment): apply it to poses held outside the map.
  std::optional<Sim3d> world_change;
  bool inertial_initialization = false;  ///< An (re-)initialisation ran and was applied.
  std::vector<map::KeyFrameId> culled;   ///< Keyframes removed.
  PointFusionResult fusion;              ///< Points merged and observations added.
};

class LocalMapper {
 public:
  /// cameras[0] = left, cameras[1] = right (optional) of the rig, in the body frame. `imu`: the
  /// IMU of the rig (enables the inertial stages when options.inertial).
  LocalMapper(const LocalMapperOptions& options, std::vector<optim::ReprojectionCamera> cameras,
              const std::optional<sensors::ImuCalibration>& imu = std::nullopt);
  /// Stops a global BA still being solved.
  ~LocalMapper();
  LocalMapper(const LocalMapper&) = delete;
  LocalMapper& operator=(const LocalMapper&) = delete;

  /// Registers a keyframe's right observations and points it created (for culling).
  void addKeyFrame(map::KeyFrameId id, RightObservations right,
                   const std::vector<map::MapPointId>& new_points);

  /// Local BA around `newest` (inertial stages with IMU), outlier removal, point and keyframe
  /// culling.
  LocalMappingResult processKeyFrame(map::Map& map, map::KeyFrameId newest);

  /// Forget all state (after a map reset), but the right-camera observations of the keyframes
  /// `kept` (sorted ids of the maps left in the atlas, map/atlas.h: a merge brings them back).
  void reset(const std::vector<map::KeyFrameId>& kept = {});

  /// Whether inertial stage `stage` (0 = initialisation, 1 and 2 = refinements) is due for a map
  /// of this age and keyframe count. Reads only options: safe from any thread.
  bool inertialStageDue(int stage, double map_age_s, int keyframes) const;

  /// Runs the inertial (re-)initialisation due at this map age, if any, with the full VI BA that
  /// follows it. It moves the whole map: call it only while no other thread uses the map (the
  /// tracker waits for the mapping thread to be idle).
  LocalMappingResult initializeInertialIfDue(map::Map& map, map::KeyFrameId newest);

  /// After a loop closure has moved the map: the global BA (global_ba_iterations), visual-inertial
  /// once the map is inertially initialised, at once where the mapping jobs run (the sequential,
  /// deterministic pipeline; the state is solved and written back as one map update, and nothing
  /// else changes the map meanwhile).
  BundleAdjustmentResult globalBundleAdjust(map::Map& map);
  /// The concurrent pipeline's global BA, ORB-SLAM3's: the problem of globalBundleAdjust() is
  /// loaded here, where the mapping jobs run, and solved in a thread of its own that neither
  /// tracking nor local mapping waits for; applyGlobalBundleAdjust() writes it into the map as it
  /// is by then (DeferredBundleAdjustment). A request while one is being solved starts once that
  /// one has been taken.
  void startGlobalBundleAdjust(map::Map& map);
  /// Where the mapping jobs run: applies a global BA whose solve has finished (with `wait`: waits
  /// for a running one, and for the one requested meanwhile), or drops it when a correction
  /// (another loop) has moved the map since its state was loaded: its solution would undo it.
  void applyGlobalBundleAdjust(map::Map& map, bool wait);
  /// Stops a global BA being solved and forgets it and any request (before its map goes);
  /// returns once its thread is idle. Called from the thread that runs the mapping jobs, or from
  /// another while none runs.
  void abandonGlobalBundleAdjust();
  /// Global BAs applied so far and their summed time [ms] (wall time of loading, solving and
  /// applying; read once the mapping jobs are done).
  int globalBaRuns() const { return global_ba_runs_; }
  double globalBaMilliseconds() const { return global_ba_ms_; }
  /// Global BAs solved in their own thread and dropped (a loop corrected the map meanwhile).
  int globalBasDropped() const { return global_bas_dropped_; }

  /// The inertial initialisation has been applied to the current map.
  bool inertialInitialized() const { return initializations_ > 0; }
  const LocalMapperOptions& options() const { return options_; }
  /// Right-camera observations of the keyframes registered since the last reset (saved maps).
  const std::map<map::KeyFrameId, RightObservations>& rightObservations() const { return right_; }

 private:
  std::vector<map::KeyFrameId> localWindow(const map::Map& map, map::KeyFrameId newest) const;
  BundleAdjustmentSettings settings(int iterations) const;
  BundleAdjustmentResult visualBundleAdjust(map::Map& map, map::KeyFrameId newest);
  BundleAdjustmentResult inertialBundleAdjust(map::Map& map, map::KeyFrameId newest);
  BundleAdjustmentResult fullInertialBundleAdjust(map::Map& map, double bias_sigma_gyro,
                                                  double bias_sigma_acc);
  /// The global BA's problem: every keyframe (inertial once initialised); none without
  /// iterations or with fewer than 2 keyframes.
  std::optional<BundleAdjustmentWindow> globalWindow(const map::Map& map) const;
  std::optional<BundleAdjustmentImu> globalImuContext();
  void cullRecentPoints(map::Map& map, map::KeyFrameId newest);
  double mapAgeSeconds(const map::Map& map, map::KeyFrameId newest) const;

  LocalMapperOptions options_;
  std::vector<optim::ReprojectionCamera> cameras_;
  std::optional<sensors::ImuCalibration> imu_;
  std::optional<KeyFramePreintegrations> preintegrations_;
  std::map<map::KeyFrameId, RightObservations> right_;
  std::vector<std::pair<map::MapPointId, map::KeyFrameId>> recent_points_;
  std::optional<PointTriangulator> triangulator_;
  PointFuser fuser_;
  int initializations_ = 0;  ///< Inertial (re-)initialisations applied to the current map.
  int global_ba_runs_ = 0;
  double global_ba_ms_ = 0.0;
  int global_bas_dropped_ = 0;
  std::unique_ptr<DeferredBundleAdjustment> global_ba_;  ///< Solving or solved in its thread.
  bool global_ba_requested_ = false;                     ///< Another loop asked for one meanwhile.
  double global_ba_solve_ms_ = 0.0;                      ///< The last solve's wall time.
  TaskThread global_ba_thread_;  ///< Last: ends (waiting for its job) before the state it uses.
  /// The bias prior of the latest full VI BA [rad/s], [m/s^2] (the global BA keeps it).
  double bias_prior_sigma_gyro_ = 0.0;
  double bias_prior_sigma_acc_ = 0.0;
};

}  // namespace superdyna::mapping
