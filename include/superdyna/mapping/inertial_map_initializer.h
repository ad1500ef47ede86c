#pragma once
// Map-level inertial initialisation (ORB-SLAM3, Campos et al. 2021, "inertial-only MAP
// estimation"): from the keyframes of a visual map and the IMU samples stored between them,
// estimate the gravity direction, the keyframe velocities, one IMU bias for the whole map and,
// optionally, the scale of the map; then move the map into a gravity-aligned world frame.
//
// Usage (stereo-inertial: scale known, estimate_scale = false; monocular-inertial: scale unknown,
// estimate_scale = true):
//
//   mapping::InertialMapInitOptions options;
//   options.estimate_scale = monocular;
//   const auto result = mapping::initializeInertialMap(map, imu.T_b_i, noise, options);
//   if (result.applied) { /* map is now gravity aligned, metric, with v_w, bg, ba per keyframe;
//                            apply result.T_new_old to any pose held outside the map */ }
//
// What it reads: every keyframe of the map that is linked to its predecessor (KeyFrame::previous,
// KeyFrame::imu_from_previous bracketing the gap), in temporal order - a gap without samples
// starts the chain anew (only the latest chain is used). The keyframe poses T_w_b are held fixed
// (the IMU poses T_w_b * T_b_i enter the estimation), so a previous visual BA should have run.
//
// What it writes when it succeeds (result.applied):
//   * the map is moved by the similarity T_new_old = (s, R_w_v, 0): keyframe poses rotate about
//     the world origin and positions scale by s, points likewise (Map::transformWorld). The new
//     world has z up (gravity (0, 0, -kGravity)); its yaw is the smallest rotation (unobservable).
//   * every keyframe of the chain gets v_w (metric, new world frame) and the common bias; keyframes
//     before the chain get the bias and zero velocity.
// With estimate_scale the camera-to-IMU lever arm enters at the initial scale: keep it small
// against the motion or re-run after a first scale estimate (as inertial_initialization.h says).
//
// Conditioning: the estimation is refused (applied = false, `reason` says why) with too few
// keyframes or too short a time span. With little motion the accelerometer bias cannot be told
// from a tilt of gravity; the prior (accel_bias_prior_sigma small, as ORB-SLAM3's first
// initialisation, and capped whenever the keyframes rotated less than
// min_rotation_for_accel_bias_deg) keeps it near zero, so gravity direction, gyroscope bias and
// velocities stay well determined. Scale estimation additionally needs min_scale_excitation of
// (metric, IMU-measured) acceleration change, or it is refused.

#include <string>

#include "superdyna/core/geometry.h"
#include "superdyna/imu/inertial_initialization.h"
#include "superdyna/map/map.h"

namespace superdyna::mapping {

struct InertialMapInitOptions {
  /// Estimate the map scale (monocular-inertial). False: scale fixed at 1 (stereo).
  bool estimate_scale = false;
  int min_keyframes = 10;       ///< Keyframes of the chain needed, >= 3.
  double min_duration_s = 2.0;  ///< Time between the first and the last of them [s], > 0.
  /// Prior std of the common gyroscope bias around zero [rad/s], > 0.
  double gyro_bias_prior_sigma = 0.1;
  /// Prior std of the accelerometer bias around zero [m/s^2], > 0. Small (ORB-SLAM3's first
  /// initialisation) makes a near-stationary start well posed; relax it in later refinements.
  double accel_bias_prior_sigma = 1e-3;
  /// Excitation guard: when the keyframe orientations differ from the first one by less than this
  /// [deg] (>= 0), the accelerometer bias is indistinguishable from a gravity tilt and its prior
  /// std is capped at unexcited_accel_bias_prior_sigma.
  double min_rotation_for_accel_bias_deg = 10.0;
  double unexcited_accel_bias_prior_sigma = 1e-3;  ///< [m/s^2], > 0.
  /// Scale estimation only: the metric acceleration must vary by at least this much over the
  /// chain [m/s^2], > 0: RMS about their mean of the keyframe intervals' mean specific forces
  /// (preintegrated velocity change / time, rotated into the world by the keyframe orientations;
  /// gravity cancels). Measured by the IMU, so independent of the arbitrary visual scale.
  double min_scale_excitation = 0.3;
  int max_iterations = 50;       ///< Ceres iterations per round, >= 1.
  int reintegration_rounds = 1;  ///< Extra rounds after re-integrating at the estimate, >= 0.

  /// Throws OptionError naming the first invalid field.
  void validate() const;
  bool operator==(const InertialMapInitOptions&) const = default;
};

struct InertialMapInitResult {
  bool applied = false;  ///< The map was changed.
  std::string reason;    ///< Why not, when !applied.
  /// The similarity that moved the map (old world -> new world), identity unless applied.
  Sim3d T_new_old;
  imu::InertialInitResult estimate;     ///< The raw estimate (frame v = the old world).
  int keyframes = 0;                    ///< Keyframes of the chain used.
  double duration_s = 0.0;              ///< Their time span [s].
  double rotation_deg = 0.0;            ///< Largest keyframe rotation from the first [deg].
  double accel_bias_prior_sigma = 0.0;  ///< The accelerometer bias prior std used [m/s^2].
};

/// Runs the inertial-only estimation on the map's keyframe chain and, on success, applies it to
/// the map (see the file comment). T_b_i: IMU pose in the body frame; noise: IMU noise model.
/// Throws OptionError for invalid options or noise; Ceres failures leave the map unchanged
/// (applied = false).
InertialMapInitResult initializeInertialMap(map::Map& map, const SE3d& T_b_i,
                                            const imu::ImuNoise& noise,
                                            const InertialMapInitOptions& options = {});

}  // namespace superdyna::mapping
