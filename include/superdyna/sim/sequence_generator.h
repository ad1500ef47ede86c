#pragma once
// Writes one synthetic stereo + IMU sequence in the EuRoC ASL layout, readable by
// io::EurocDataset and by other EuRoC tools:
//
//   mav0/cam{0,1}/{sensor.yaml, data.csv, data/<t_ns>.png}   752x480 gray images, 20 Hz
//   mav0/cam{0,1}/mask/<t_ns>.png                            16-bit instance ids (0 = background;
//                                                            unlabelled agents read as background)
//   mav0/cam{0,1}/segmentation/<t_ns>.png                    optional VIODE-like colour labels
//   mav0/imu0/{sensor.yaml, data.csv}                        200 Hz gyro + accel
//   mav0/state_groundtruth_estimate0/{sensor.yaml, data.csv} body pose, velocity, true biases
//   mav0/instances.csv                                       id -> class, moving?, lifetime
//   mav0/instance_states.csv                                 per frame: id, moving, pixels, class
//   mav0/frame_stats.csv                                     per frame: agent / moving pixels,
//                                                            FAST corners on moving agents
//   mav0/segmentation_colors.csv                             id -> r,g,b (with segmentation)
//   mav0/landmarks.csv                                       ground-truth 3D points on surfaces
//   mav0/photometric.csv                                     per frame: gains, blur (when on)
//   simulation.yaml                                          the effective options and summary
//
// Image timestamps are mid-exposure: with motion blur, an image averages the scene over
// [t - exposure/2, t + exposure/2] while its mask, depth and ground truth are those at t.

#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>

#include "superdyna/core/camera_model.h"
#include "superdyna/sim/illumination.h"
#include "superdyna/sim/imu_simulator.h"
#include "superdyna/sim/motion_source.h"
#include "superdyna/sim/sensor_faults.h"
#include "superdyna/sim/world_builder.h"

namespace superdyna::sim {

/// The simulated stereo rig: EuRoC-like intrinsics and camera extrinsics, and the IMU. The body
/// frame is the frame of the motion (the ground truth); by default the IMU is the body frame, as in
/// EuRoC, or it is mounted at imu_offset_m turned by imu_rotation_deg.
struct RigOptions {
  int width = 752;
  int height = 480;
  double fx = 458.654, fy = 457.296, cx = 367.215, cy = 248.375;  ///< EuRoC cam0 [px].
  bool distortion = false;  ///< Apply EuRoC cam0's radial-tangential distortion.
  double baseline_m = 0.11;
  double camera_rate_hz = 20.0;
  /// Position of the IMU origin in the body frame [m].
  Eigen::Vector3d imu_offset_m = Eigen::Vector3d::Zero();
  /// Orientation of the IMU in the body frame as a rotation vector (axis times angle) [deg].
  Eigen::Vector3d imu_rotation_deg = Eigen::Vector3d::Zero();

  CameraModel cameraModel() const;
  /// Camera poses in the body frame: EuRoC cam0's T_BS; cam1 shifted by the baseline along
  /// cam0's x axis, same orientation.
  SE3d T_b_c0() const;
  SE3d T_b_c1() const;
  /// IMU pose in the body frame (written as imu0's T_BS): R_b_i = Exp(imu_rotation_deg), t_b_i =
  /// imu_offset_m.
  SE3d T_b_i() const;
  void validate() const;
};

/// The static world of a sequence, as the world_source section of its simulation.yaml records
/// it: what rebuilds that world exactly (simulate --world-of). A sequence made with --world-of
/// records the source it reused, so chains keep the first sequence's world.
struct WorldSource {
  std::filesystem::path sequence;  ///< The folder it was read from (for messages; not written).
  MotionSourceOptions motion;      ///< That sequence's motion (trajectory as an absolute path).
  double knot_spacing_s = 0.1;
  SceneType scene = SceneType::kStreet;
  std::uint64_t seed = 1;
  std::optional<std::filesystem::path> texture_dir;  ///< Absolute.
  double background_contrast = 1.0;  ///< WorldOptions::background_contrast (1 when not written).
  int texture_variety = 0;           ///< WorldOptions::texture_variety (0 when not written).
  std::uint64_t fingerprint = 0;     ///< staticWorldFingerprint of that world.
};

/// Reads SEQ/simulation.yaml's world_source section; InputError naming the file and the key
/// (a sequence written before world_source existed has none: regenerate it).
WorldSource readWorldSource(const std::filesystem::path& sequence);

struct SimulationOptions {
  std::filesystem::path output_dir;
  bool overwrite = false;  ///< Allow writing into a non-empty output folder.
  MotionSourceOptions motion;
  WorldOptions world;
  std::optional<std::filesystem::path> texture_dir;  ///< Photos to texture the world with.
  RigOptions rig;
  ImuNoiseOptions imu;
  bool noise = true;                    ///< IMU noise and bias walk, image noise.
  double pixel_noise_sigma = 2.0;       ///< Image noise std when noise is on [gray levels].
  IlluminationOptions illumination;     ///< Exposure gain over time (default: constant 1).
  double motion_blur_exposure_s = 0.0;  ///< Exposure time for motion blur (0 = none) [s].
  /// Sub-frames per blurred image: 0 = automatic from the image motion over the exposure
  /// (consecutive sub-frames at most motion_blur_step_px apart, up to motion_blur_max_samples).
  int motion_blur_samples = 0;
  double motion_blur_step_px = 1.0;
  int motion_blur_max_samples = 15;
  bool semantic_color = false;  ///< Also write VIODE-like colour segmentation images.
  int landmark_count = 2000;    ///< Ground-truth landmarks to write (0 = none).
  SensorFaultOptions faults;    ///< Damage written into the sequence (default: none).
  double knot_spacing_s = 0.1;  ///< Spline knot spacing fitted to the motion [s].
  std::uint64_t seed = 1;       ///< Seeds the world, agents, IMU noise and image noise.
  /// Reuse the static world of another sequence (its ground, buildings or room, clutter, and so
  /// its world frame); the agents, noise and motion are this sequence's (seed, motion). The
  /// scene and textures are the source's. Its static world must rebuild to the recorded
  /// fingerprint and this camera path must stay inside it.
  std::optional<WorldSource> world_of;
  /// Optional PNG showing one cam0 frame beside its colour-coded instance mask.
  std::optional<std::filesystem::path> preview_path;
  int preview_frame = 0;  ///< Index of the frame the preview shows (clamped to the last).

  void validate() const;
};

struct SimulationSummary {
  int frames = 0;
  std::size_t imu_samples = 0;
  int static_agents = 0;
  int moving_agents = 0;
  double mean_moving_in_view = 0.0;  ///< Moving agents with >= 50 pixels in cam0, per frame.
  double max_moving_in_view = 0.0;
  double mean_agent_coverage = 0.0;  ///< Fraction of cam0 pixels on agents, per frame.
  /// Fraction of cam0 pixels on agents moving at the frame's time: mean and largest over frames.
  double mean_moving_coverage = 0.0;
  double max_moving_coverage = 0.0;
  double mean_unlabelled_moving_coverage = 0.0;  ///< Of those, on unlabelled agents (mean).
  /// Share of the FAST corners of cam0 (threshold 20) that lie on moving agents, per frame.
  double mean_moving_corner_share = 0.0;
  double max_moving_corner_share = 0.0;
  /// Fraction of cam0 pixels that see a surface (textured world or agent, not the sky), per frame.
  double mean_surface_coverage = 0.0;
  double path_length_m = 0.0;
  double mean_blur_samples = 1.0;        ///< Sub-frames per image, over both cameras.
  double mean_exposure_motion_px = 0.0;  ///< Largest image motion over the exposure, per image.
  double max_exposure_motion_px = 0.0;
  double min_gain = 1.0, max_gain = 1.0;  ///< Exposure gain over both cameras.
  double seconds = 0.0;                   ///< Wall-clock time of the generation.
};

/// Called after each frame with (frames done, frames total).
using ProgressCallback = std::function<void(int done, int total)>;

/// Generates and writes the sequence. Throws OptionError / InputError with context (e.g. the
/// output folder is not empty and overwrite is off, the trajectory is too short).
SimulationSummary generateSequence(const SimulationOptions& options,
                                   const ProgressCallback& progress = {});

}  // namespace superdyna::sim
