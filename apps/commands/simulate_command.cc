#include "commands/simulate_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <chrono>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/core/error.h"
#include "superdyna/sim/sequence_generator.h"
#ifdef SUPERDYNA_WITH_ROSBAG
#include "superdyna/bag/sequence_bag_writer.h"
#endif

namespace superdyna::apps {

namespace fs = std::filesystem;

namespace {

class SimulateCommand : public Command {
 public:
  explicit SimulateCommand(CLI::App& app) {
    sub_ = app.add_subcommand(
        "simulate",
        "Write a synthetic dynamic-scene sequence in EuRoC layout: stereo images, IMU, exact "
        "ground truth, instance masks, moving and parked vehicles and pedestrians");
    addOutputOptions();
    addMotionOptions();
    addSceneOptions();
    addSensorOptions();
    addPhotometricOptions();
    addFaultOptions();
    sub_->footer(
        "Output: OUT/mav0/{cam0,cam1,imu0,state_groundtruth_estimate0} as in EuRoC, plus per-frame "
        "instance masks (camX/mask, 16-bit, 0 = background), instances.csv, instance_states.csv, "
        "frame_stats.csv (per-frame pixels and FAST corners on moving agents), landmarks.csv, "
        "photometric.csv (per-frame gains and blur, with photometric challenges) "
        "and OUT/simulation.yaml. Deterministic for a given --seed.");
  }

  CLI::App* subcommand() const override { return sub_; }

  int run() override {
    applyChoices();
    checkBagOutput();
    spdlog::info("simulating {} s of a {} scene, dynamic level {}, mover pattern {}, into {}",
                 options_.motion.duration_s, sim::toString(options_.world.scene),
                 sim::toString(options_.world.dynamic),
                 sim::toString(options_.world.pattern.pattern), options_.output_dir.string());
    const auto started = std::chrono::steady_clock::now();
    int last_reported = -1;
    const auto progress = [&](int done, int total) {
      const int percent = 100 * done / total;
      if (percent / 10 == last_reported / 10 && done != total) return;
      last_reported = percent;
      const double elapsed =
          std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
      spdlog::info("frame {}/{} ({}%), {:.1f} frames/s, {:.0f} s left", done, total, percent,
                   done / elapsed, elapsed / done * (total - done));
    };
    const sim::SimulationSummary summary = sim::generateSequence(options_, progress);
    fmt::print(
        "wrote {} stereo frames, {} IMU samples, {} static and {} moving agents "
        "({:.1f} moving in view on average, at most {:.0f}; agents cover {:.1f}% of the image, "
        "surfaces {:.1f}%), {:.1f} m of path, in {:.1f} s\n"
        "  moving agents: {:.1f}% of the image on average, at most {:.1f}% (unlabelled {:.1f}%); "
        "{:.1f}% of the FAST corners on average, at most {:.1f}%\n  -> {}\n",
        summary.frames, summary.imu_samples, summary.static_agents, summary.moving_agents,
        summary.mean_moving_in_view, summary.max_moving_in_view,
        100.0 * summary.mean_agent_coverage, 100.0 * summary.mean_surface_coverage,
        summary.path_length_m, summary.seconds, 100.0 * summary.mean_moving_coverage,
        100.0 * summary.max_moving_coverage, 100.0 * summary.mean_unlabelled_moving_coverage,
        100.0 * summary.mean_moving_corner_share, 100.0 * summary.max_moving_corner_share,
        (options_.output_dir / "mav0").string());
    if (rosbag_) writeBag();
    return 0;
  }

 private:
  void addOutputOptions() {
    sub_->add_option("--out", options_.output_dir, "Output folder (created; must be empty)")
        ->required();
    sub_->add_flag("--overwrite", options_.overwrite, "Allow a non-empty output folder");
    sub_->add_option("--seed", options_.seed, "Seed of the world, agents and noise")
        ->capture_default_str();
    sub_->add_option("--preview", options_.preview_path,
                     "Also write a PNG of one cam0 frame beside its colour-coded instance mask");
    sub_->add_option("--preview-frame", options_.preview_frame, "Frame index the preview shows")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
  }

  void addMotionOptions() {
    sub_->add_option("--trajectory", trajectory_,
                     "Real trajectory giving the motion (TUM, EuRoC CSV or KITTI poses); "
                     "default: a procedural flight sized to the scene")
        ->check(CLI::ExistingFile);
    sub_->add_option("--trajectory-format", trajectory_format_, "Format of --trajectory")
        ->check(CLI::IsMember({"auto", "tum", "euroc", "kitti"}))
        ->capture_default_str();
    sub_->add_option("--trajectory-times", trajectory_times_, "KITTI times file")
        ->check(CLI::ExistingFile);
    sub_->add_option("--segment", segment_,
                     "Use the 'seq: N' block of a multi-recording file (OpenLORIS)");
    sub_->add_option("--motion-convention", convention_,
                     "Axes of the trajectory's frame: auto, body (EuRoC IMU, x up, cameras along "
                     "z), tum-vi (TUM-VI IMU, z up, cameras along -y), forward-x (robot base, x "
                     "forward z up), camera (KITTI)")
        ->check(CLI::IsMember({"auto", "body", "tum-vi", "forward-x", "camera"}))
        ->capture_default_str();
    sub_->add_option("--start", options_.motion.start_s, "Skip this much of the trajectory [s]")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    sub_->add_option("--duration", options_.motion.duration_s, "Sequence length [s]")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
  }

  void addSceneOptions() {
    sub_->add_option("--world-of", world_of_,
                     "Reuse the static world (ground, buildings or room, clutter; not the agents) "
                     "of an earlier simulated sequence, so that both ground truths share its world "
                     "frame: give this sequence another --seed and part of the trajectory "
                     "(--start, --duration) inside that world")
        ->check(CLI::ExistingDirectory);
    sub_->add_option("--scene", scene_, "World: street, parking or indoor")
        ->check(CLI::IsMember({"street", "parking", "indoor"}))
        ->capture_default_str();
    sub_->add_option("--dynamic", dynamic_,
                     "Moving agents in view: none (0), low (~2), mid (~5), high (~10); every level "
                     "also has parked cars / standing people")
        ->check(CLI::IsMember({"none", "low", "mid", "high"}))
        ->capture_default_str();
    addMoverOptions();
    sub_->add_option("--textures", texture_dir_,
                     "Folder of photos (.png/.jpg) to texture the world with instead of procedural "
                     "textures")
        ->check(CLI::ExistingDirectory);
    sub_->add_option("--background-contrast", options_.world.background_contrast,
                     "Contrast of the static world's textures (ground, walls, clutter; not the "
                     "parked or moving agents), 1 = as usual: below 1 a weakly textured "
                     "background, on which parked cars and standing people hold more of the "
                     "features")
        ->check(CLI::Range(0.01, 1.0))
        ->capture_default_str();
    sub_->add_option("--texture-variety", options_.world.texture_variety,
                     "Repeated textures, for testing place recognition against aliasing: the "
                     "static surfaces of each kind share this many textures, so different places "
                     "look alike; 0 gives every surface its own")
        ->check(CLI::Range(0, 1000))
        ->capture_default_str();
    sub_->add_option("--parked-density", options_.world.parked_density,
                     "Places tried for parked cars and standing people per metre of path, "
                     "relative to the scene's usual number (a full parking lot: 4, about 2.5x the "
                     "agents; places taken are skipped); other values also draw other movers")
        ->check(CLI::Range(0.1, 10.0))
        ->capture_default_str();
    sub_->add_option("--rosbag", rosbag_,
                     "Also write the sequence as a ROS 1 bag (lz4) in the layout of "
                     "--rosbag-layout; the calibration stays in the folder");
    sub_->add_option("--rosbag-layout", rosbag_layout_,
                     "viode: /cam0/image_raw, /cam1/image_raw, /cam0/segmentation and "
                     "/cam1/segmentation with --semantic-color, /imu0, /odometry; openloris: "
                     "OpenLORIS-Scene's D435i, /d400/color/image_raw (rgb8, left camera), "
                     "/d400/gyro/sample (200 Hz) and /d400/accel/sample (62.5 Hz) published apart, "
                     "no ground-truth topic (use the folder's)")
        ->check(CLI::IsMember({"viode", "openloris"}))
        ->capture_default_str();
    sub_->add_flag("--semantic-color", options_.semantic_color,
                   "Also write VIODE-like colour segmentation images (camX/segmentation)");
    sub_->add_option("--landmarks", options_.landmark_count,
                     "Ground-truth 3D landmarks to write (landmarks.csv)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
  }

  /// Movers that hurt a SLAM without moving-object handling (issue 14), on top of --dynamic.
  void addMoverOptions() {
    const std::string group = "Hard movers";
    sub_->add_option("--dynamic-pattern", pattern_,
                     "Groups of movers close to the camera, moving coherently, one group at a "
                     "time, on top of --dynamic: bus (a 12 m bus crossing the view 3-6 m ahead or "
                     "driving along it 3-6 m beside), convoy (4 cars in a line, 4-7 m), crowd (10 "
                     "people walking one way, 2-5 m), none")
        ->check(CLI::IsMember({"none", "bus", "convoy", "crowd"}))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--pattern-size", options_.world.pattern.group_size,
                     "Agents per group (0 = the pattern's default: bus 1, convoy 4, crowd 10)")
        ->check(CLI::Range(0, 50))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--pattern-distance", pattern_distance_,
                     "MIN,MAX distance of the groups from the camera [m] (ahead when crossing, "
                     "beside when moving along the view); default: the pattern's")
        ->expected(2)
        ->delimiter(',')
        ->group(group);
    sub_->add_flag("--slow-movers", options_.world.pattern.slow,
                   "Slow groups, whose image motion stays within the robust kernels: vehicles at "
                   "0.5-1.5 m/s, people at 0.3-0.6 m/s")
        ->group(group);
    sub_->add_option("--unlabelled", options_.world.unlabelled_share,
                     "Share of the moving agents given the class 'unlabelled': listed in "
                     "instances.csv and instance_states.csv but left out of camX/mask (a mover "
                     "the segmenter does not know); the images do not change")
        ->check(CLI::Range(0.0, 1.0))
        ->capture_default_str()
        ->group(group);
  }

  void addSensorOptions() {
    sub_->add_option("--noise", noise_, "IMU noise + bias random walk and image noise: on or off")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    sub_->add_option("--distortion", distortion_,
                     "Apply EuRoC cam0's radial-tangential distortion: on or off")
        ->check(CLI::IsMember({"on", "off"}))
        ->capture_default_str();
    sub_->add_option("--baseline", options_.rig.baseline_m, "Stereo baseline [m]")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub_->add_option("--imu-offset", imu_offset_,
                     "IMU origin in the body frame, X,Y,Z [m] (default 0,0,0: the IMU is the body "
                     "frame, as in EuRoC). The ground truth stays the body's; imu0/sensor.yaml "
                     "gets the IMU's T_BS and the IMU measures at its own origin")
        ->expected(3)
        ->delimiter(',');
    sub_->add_option("--imu-rotation", imu_rotation_,
                     "IMU orientation in the body frame as a rotation vector RX,RY,RZ (axis times "
                     "angle) [deg], default 0,0,0")
        ->expected(3)
        ->delimiter(',');
  }

  /// Motion blur and illumination changes, to stress the visual front end.
  void addPhotometricOptions() {
    const std::string group = "Photometric challenges";
    sub_->add_option("--exposure-ms", exposure_ms_,
                     "Exposure time for motion blur [ms], 0 = sharp. Each image averages "
                     "sub-frames over [t - E/2, t + E/2] (its timestamp t is mid-exposure) for "
                     "the camera and the moving agents; masks and depth stay those at t")
        ->check(CLI::Range(0.0, 100.0))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--blur-samples", options_.motion_blur_samples,
                     "Sub-frames per blurred image; 0 = automatic: enough that consecutive "
                     "sub-frames are at most --blur-step px apart (rendering time grows with it)")
        ->check(CLI::Range(0, 64))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--blur-step", options_.motion_blur_step_px,
                     "Automatic sub-frames: largest image motion between two of them [px]")
        ->check(CLI::Range(0.1, 10.0))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--blur-max-samples", options_.motion_blur_max_samples,
                     "Automatic sub-frames: at most this many per image")
        ->check(CLI::Range(1, 64))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--illumination", illumination_,
                     "Exposure gain effects, comma-separated: none, drift (slow sinusoid), steps "
                     "(abrupt exposure jumps, alternately brighter and darker), flicker "
                     "(independent per frame and camera), all. The gain multiplies the radiance "
                     "before sensor noise, clipping to [0, 255] and rounding")
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--illumination-gain", options_.illumination.base_gain,
                     "Constant gain of both cameras, whatever --illumination; below 1 a dim "
                     "scene (lower contrast against the same sensor noise)")
        ->check(CLI::Range(0.05, 4.0))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--illumination-drift", options_.illumination.drift_amplitude,
                     "drift: gain 1 + A sin(2 pi t / period)")
        ->check(CLI::Range(0.0, 0.9))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--illumination-drift-period", options_.illumination.drift_period_s,
                     "drift: period [s]")
        ->check(CLI::PositiveNumber)
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--illumination-step", options_.illumination.step_amplitude,
                     "steps: gain levels within [1 / (1 + A), 1 + A], |log gain| at least half of "
                     "log(1 + A); the first interval has gain 1")
        ->check(CLI::Range(0.0, 4.0))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--illumination-step-interval", options_.illumination.step_interval_s,
                     "steps: time between exposure jumps [s]")
        ->check(CLI::PositiveNumber)
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--illumination-flicker", options_.illumination.flicker_amplitude,
                     "flicker: gain 1 + A u, u uniform in [-1, 1]")
        ->check(CLI::Range(0.0, 0.5))
        ->capture_default_str()
        ->group(group);
    sub_->add_option("--stereo-gain-ratio", options_.illumination.stereo_gain_ratio,
                     "cam1 gain / cam0 gain (auto-exposure mismatch), whatever --illumination")
        ->check(CLI::Range(0.25, 4.0))
        ->capture_default_str()
        ->group(group);
  }

  /// Damage written the way real sensors produce it (sim/sensor_faults.h).
  void addFaultOptions() {
    const std::string group = "Sensor faults (times in s after the first frame, T0:T1 half-open)";
    sub_->add_option("--drop-frames", drop_frames_,
                     "Dropped frames: a rate in [0, 1) with a decimal point (0.05: each frame "
                     "dropped with that probability, from --seed) or frame indices 10,11,40; "
                     "their rows and images are missing from both cameras")
        ->group(group);
    sub_->add_option("--imu-gap", imu_gaps_,
                     "T0:T1: imu0/data.csv has no rows in this interval (several allowed)")
        ->group(group);
    sub_->add_option("--imu-nan", imu_nan_,
                     "T0:T1: imu0/data.csv rows in this interval hold nan (several allowed)")
        ->group(group);
    sub_->add_option("--black-frames", black_frames_,
                     "T0:T1: both cameras' images in this interval are black (several allowed)")
        ->group(group);
    sub_->add_option("--overexposed-frames", overexposed_frames_,
                     "T0:T1: both cameras' images in this interval are saturated white (several "
                     "allowed)")
        ->group(group);
    sub_->add_option("--missing-cam1", missing_cam1_,
                     "T0:T1: cam1 has no rows or images in this interval, cam0 goes on (several "
                     "allowed)")
        ->group(group);
    sub_->add_option("--repeat-timestamps", repeated_rows_,
                     "T0:T1: camera and IMU rows in this interval are each written twice (same "
                     "timestamp; several allowed)")
        ->group(group);
    sub_->add_option("--swap-timestamps", swapped_rows_,
                     "T0:T1: each two consecutive camera and IMU rows in this interval are "
                     "written in reverse time order (several allowed)")
        ->group(group);
    sub_->add_option("--imu-saturate", imu_saturated_,
                     "T0:T1: imu0/data.csv rows in this interval are at the sensor's range "
                     "(+-2000 deg/s, +-16 g, in imu0/sensor.yaml) on every axis (several allowed)")
        ->group(group);
    sub_->add_option("--time-offset", options_.faults.imu_time_offset_s,
                     "Camera-IMU time offset [s], |offset| < 1: every IMU timestamp is written "
                     "this much late (ground truth and images keep the true times)")
        ->group(group);
  }

  void applyFaults() {
    if (drop_frames_) sim::parseDropFrames(*drop_frames_, &options_.faults);
    for (const std::string& text : imu_gaps_)
      options_.faults.imu_gaps.push_back(sim::parseFaultInterval(text, "--imu-gap"));
    for (const std::string& text : imu_nan_)
      options_.faults.imu_nan.push_back(sim::parseFaultInterval(text, "--imu-nan"));
    for (const std::string& text : black_frames_)
      options_.faults.black_frames.push_back(sim::parseFaultInterval(text, "--black-frames"));
    for (const std::string& text : overexposed_frames_) {
      options_.faults.overexposed_frames.push_back(
          sim::parseFaultInterval(text, "--overexposed-frames"));
    }
    for (const std::string& text : missing_cam1_)
      options_.faults.missing_cam1.push_back(sim::parseFaultInterval(text, "--missing-cam1"));
    for (const std::string& text : repeated_rows_)
      options_.faults.repeated_rows.push_back(sim::parseFaultInterval(text, "--repeat-timestamps"));
    for (const std::string& text : swapped_rows_)
      options_.faults.swapped_rows.push_back(sim::parseFaultInterval(text, "--swap-timestamps"));
    for (const std::string& text : imu_saturated_)
      options_.faults.imu_saturated.push_back(sim::parseFaultInterval(text, "--imu-saturate"));
  }

  void applyChoices() {
    applyFaults();
    options_.motion.trajectory_file = trajectory_;
    options_.motion.read.format = io::parseTrajectoryFormat(trajectory_format_);
    options_.motion.read.kitti_times = trajectory_times_;
    options_.motion.read.segment = segment_;
    options_.motion.convention = sim::parseMotionConvention(convention_);
    options_.world.scene = sim::parseSceneType(scene_);
    options_.world.dynamic = sim::parseDynamicLevel(dynamic_);
    options_.world.pattern.pattern = sim::parseMoverPattern(pattern_);
    if (!pattern_distance_.empty()) {
      options_.world.pattern.min_distance_m = pattern_distance_.at(0);
      options_.world.pattern.max_distance_m = pattern_distance_.at(1);
    }
    options_.texture_dir = texture_dir_;
    options_.noise = noise_ == "on";
    options_.rig.distortion = distortion_ == "on";
    if (!imu_offset_.empty()) options_.rig.imu_offset_m = vector3(imu_offset_);
    if (!imu_rotation_.empty()) options_.rig.imu_rotation_deg = vector3(imu_rotation_);
    options_.motion_blur_exposure_s = 1e-3 * exposure_ms_;
    sim::setIlluminationModes(illumination_, &options_.illumination);
    if (world_of_) applyWorldOf(*world_of_);
  }

  /// --rosbag: fails before the simulation when the bag cannot be written.
  void checkBagOutput() const {
    if (!rosbag_) return;
#ifdef SUPERDYNA_WITH_ROSBAG
    if (fs::exists(*rosbag_)) {
      throw OptionError("--rosbag", fmt::format("{} exists already; a bag is never overwritten",
                                                rosbag_->string()));
    }
#else
    throw OptionError("--rosbag",
                      "this build has no ROS bag support: install Debian's librosbag-storage-dev, "
                      "libsensor-msgs-dev and libnav-msgs-dev and build again (scripts/setup.sh)");
#endif
  }

  void writeBag() const {
#ifdef SUPERDYNA_WITH_ROSBAG
    const auto counts = rosbag_layout_ == "openloris"
                            ? bag::writeOpenlorisBag(options_.output_dir, *rosbag_, "lz4")
                            : bag::writeViodeBag(options_.output_dir, *rosbag_, "lz4");
    std::string listed;
    for (const auto& [topic, messages] : counts)
      listed += fmt::format("{}{} {}", listed.empty() ? "" : ", ", topic, messages);
    fmt::print("  -> {} ({} layout, lz4: {})\n", rosbag_->string(), rosbag_layout_, listed);
#endif
  }

  /// The scene and textures come with the reused world.
  void applyWorldOf(const fs::path& sequence) {
    options_.world_of = sim::readWorldSource(sequence);
    const sim::WorldSource& source = *options_.world_of;
    if (sub_->count("--scene") > 0 && options_.world.scene != source.scene) {
      throw OptionError("--scene", fmt::format("the world of {} is a {} scene", sequence.string(),
                                               sim::toString(source.scene)));
    }
    if (texture_dir_) {
      throw OptionError("--textures", "the reused world of --world-of brings its own textures");
    }
    if (sub_->count("--background-contrast") > 0 &&
        options_.world.background_contrast != source.background_contrast) {
      throw OptionError("--background-contrast",
                        fmt::format("the world of {} has background contrast {}", sequence.string(),
                                    source.background_contrast));
    }
    if (sub_->count("--texture-variety") > 0 &&
        options_.world.texture_variety != source.texture_variety) {
      throw OptionError("--texture-variety",
                        fmt::format("the world of {} has texture variety {}", sequence.string(),
                                    source.texture_variety));
    }
    options_.world.scene = source.scene;
    options_.world.background_contrast = source.background_contrast;
    options_.world.texture_variety = source.texture_variety;
    options_.texture_dir = source.texture_dir;
    if (fs::weakly_canonical(fs::absolute(sequence)) ==
        fs::weakly_canonical(fs::absolute(options_.output_dir))) {
      throw OptionError("--out", "is the --world-of sequence itself");
    }
  }

  static Eigen::Vector3d vector3(const std::vector<double>& values) {
    return Eigen::Vector3d(values.at(0), values.at(1), values.at(2));
  }

  CLI::App* sub_ = nullptr;
  sim::SimulationOptions options_;
  std::optional<fs::path> trajectory_;
  std::string trajectory_format_ = "auto";
  std::optional<fs::path> trajectory_times_;
  std::optional<int> segment_;
  std::string convention_ = "auto";
  std::string scene_ = "street";
  std::string dynamic_ = "mid";
  std::string pattern_ = "none";
  std::vector<double> pattern_distance_;
  std::optional<fs::path> texture_dir_;
  std::optional<fs::path> rosbag_;
  std::string rosbag_layout_ = "viode";
  std::optional<fs::path> world_of_;
  std::string noise_ = "on";
  std::string distortion_ = "off";
  std::vector<double> imu_offset_;
  std::vector<double> imu_rotation_;
  double exposure_ms_ = 0.0;
  std::string illumination_ = "none";
  std::optional<std::string> drop_frames_;
  std::vector<std::string> imu_gaps_;
  std::vector<std::string> imu_nan_;
  std::vector<std::string> black_frames_;
  std::vector<std::string> overexposed_frames_;
  std::vector<std::string> missing_cam1_;
  std::vector<std::string> repeated_rows_;
  std::vector<std::string> swapped_rows_;
  std::vector<std::string> imu_saturated_;
};

}  // namespace

std::unique_ptr<Command> makeSimulateCommand(CLI::App& app) {
  return std::make_unique<SimulateCommand>(app);
}

}  // namespace superdyna::apps
