#include "commands/run_command.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <csignal>
#include <cstdio>
#include <cstdlib>
#include <filesystem>
#include <map>
#include <mutex>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <set>
#include <string>
#include <utility>

#include "commands/output_files.h"
#include "superdyna/core/error.h"
#include "superdyna/core/process_memory.h"
#include "superdyna/eval/evaluate.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/io/euroc_dataset.h"
#include "superdyna/io/kitti_dataset.h"
#ifdef SUPERDYNA_WITH_ROSBAG
#include "superdyna/bag/bag_segmenter.h"
#include "superdyna/bag/bag_source.h"
#endif
#include "superdyna/io/trajectory_io.h"
#include "superdyna/map/map_file.h"
#include "superdyna/system/dynamic_log.h"
#include "superdyna/system/frame_log.h"
#include "superdyna/system/frame_overlays.h"
#include "superdyna/system/system.h"

namespace superdyna::apps {

namespace fs = std::filesystem;

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

void printTimings(const system::SystemOptions& options, const system::TimingSummary& t) {
  fmt::print(
      "timing per frame (mean ms): extract {:.2f}, stereo {:.2f}, track {:.2f}, keyframe + local "
      "BA {:.2f} ({} keyframes; per keyframe {:.2f} ms)\n",
      t.meanMs(t.total.extract_ms), t.meanMs(t.total.stereo_ms), t.meanMs(t.total.track_ms),
      t.meanMs(t.total.local_ba_ms), t.keyframes,
      t.keyframes > 0 ? t.total.local_ba_ms / static_cast<double>(t.keyframes) : 0.0);
  if (options.tracker.dynamic.mode != dynamic::DynamicMode::kOff ||
      options.tracker.dynamic.geometric) {
    const system::MovingObjectCounts& m = t.moving_objects;
    fmt::print(
        "moving-object test ({}): {:.3f} ms per frame (part of track); dropped {} of {} keypoints "
        "({:.2f} %, {} by the geometric test); object-frames {} moving, {} static, {} unverified\n",
        dynamic::toString(options.tracker.dynamic.mode), t.meanMs(t.total.moving_objects_ms),
        m.dropped, m.keypoints,
        m.keypoints > 0 ? 100.0 * static_cast<double>(m.dropped) / static_cast<double>(m.keypoints)
                        : 0.0,
        m.geometric_dropped, m.moving, m.static_objects, m.unverified);
  }
  if (options.deterministic) {
    const double cpu_ms = t.busy.front_end_ms + t.busy.extraction_helper_ms +
                          t.busy.segmentation_ms + t.busy.tracking_ms;
    fmt::print(
        "pipeline: deterministic (sequential), {:.1f} FPS wall clock over {:.2f} s; CPU time "
        "{:.1f} s ({:.1f} ms per frame), of which extraction helper {:.1f} s, segmentation "
        "thread {:.1f} s\n",
        t.framesPerSecond(), t.wall_s, cpu_ms / 1e3, t.meanMs(cpu_ms),
        t.busy.extraction_helper_ms / 1e3, t.busy.segmentation_ms / 1e3);
    return;
  }
  const auto busy = [&](double ms) {
    return fmt::format("{:.1f} s ({:.0f} %)", ms / 1e3,
                       t.wall_s > 0 ? ms / (10.0 * t.wall_s) : 0.0);
  };
  fmt::print(
      "pipeline: concurrent, {:.1f} FPS wall clock over {:.2f} s; thread CPU time (share of the "
      "wall clock): front end {}, extraction helper {}, segmentation {}, tracking {}, local "
      "mapping {}, loop closing {}\n",
      t.framesPerSecond(), t.wall_s, busy(t.busy.front_end_ms), busy(t.busy.extraction_helper_ms),
      busy(t.busy.segmentation_ms), busy(t.busy.tracking_ms), busy(t.busy.mapping_ms),
      busy(t.busy.loop_ms));
}

/// The numbers `run` prints at the end, for tools (superdyna sweep): per-frame means in ms,
/// thread CPU times in s.
nlohmann::json runStatsJson(const system::System& slam, bool stopped) {
  const system::TimingSummary& t = slam.timings();
  const auto mean = [&](double total_ms) { return t.meanMs(total_ms); };
  return {
      {"frames", t.frames},
      {"stopped", stopped},
      {"wall_s", t.wall_s},
      {"fps", t.framesPerSecond()},
      {"lost_frames", slam.lostFrames()},
      {"map_resets", slam.resets()},
      {"relocalizations", slam.relocalizations()},
      {"map_merges", slam.loopSummary().merges.size()},
      {"keyframes", t.keyframes},
      {"deterministic", slam.options().deterministic},
      {"mean_ms_per_frame",
       {{"extract", mean(t.total.extract_ms)},
        {"stereo", mean(t.total.stereo_ms)},
        {"track", mean(t.total.track_ms)},
        {"moving_objects", mean(t.total.moving_objects_ms)},
        {"keyframe_local_ba", mean(t.total.local_ba_ms)},
        {"segment", mean(t.segment_ms)},
        {"propagate_masks", mean(t.propagate_ms)}}},
      {"thread_cpu_s",
       {{"front_end", t.busy.front_end_ms / 1e3},
        {"extraction_helper", t.busy.extraction_helper_ms / 1e3},
        {"segmentation", t.busy.segmentation_ms / 1e3},
        {"tracking", t.busy.tracking_ms / 1e3},
        {"local_mapping", t.busy.mapping_ms / 1e3},
        {"loop_closing", t.busy.loop_ms / 1e3}}},
  };
}

void printSegmentation(const system::TimingSummary& t) {
  const auto mean = [](double total_ms, std::size_t n) { return n > 0 ? total_ms / n : 0.0; };
  fmt::print(
      "segmentation: {} frames segmented ({:.2f} ms each, beside the extraction), {} with masks "
      "propagated ({:.2f} ms each); {:.2f} ms per frame\n",
      t.segmented_frames, mean(t.segment_ms, t.segmented_frames), t.propagated_frames,
      mean(t.propagate_ms, t.propagated_frames), t.meanMs(t.segment_ms + t.propagate_ms));
}

/// Writes every `every`-th frame's overlay (system::FrameOverlays) into `dir` as a PNG file.
class OverlayWriter {
 public:
  OverlayWriter(fs::path dir, int every, bool moving_objects,
                const dynamic::MovingObjectOptions& dynamic)
      : dir_(std::move(dir)), overlays_(every, moving_objects, dynamic) {
    fs::create_directories(dir_);
  }

  void remember(const sensors::FrameBundle& bundle, const tracking::Frame& frame) {
    overlays_.remember(bundle, frame);
  }

  void write(const tracking::TrackingResult& result) {
    const std::optional<system::FrameOverlay> overlay = overlays_.draw(result);
    if (!overlay) return;
    const fs::path file = dir_ / fmt::format("overlay_{:06d}.png", overlay->index);
    if (!cv::imwrite(file.string(), overlay->image)) {
      throw InputError(InputLocation{file}, "cannot write the overlay image");
    }
  }

 private:
  fs::path dir_;
  system::FrameOverlays overlays_;
};

void printMatchCounts(const system::System& slam) {
  const system::MatchCounts& m = slam.timings().matches;
  fmt::print(
      "matches (class-wise {}): stereo {} ({} cross-class), map-to-frame {} ({} cross-class); "
      "map points {} ({} cross-class)\n",
      slam.options().front_end.features.class_wise_matching ? "on" : "off", m.stereo,
      m.stereo_cross_class, m.map, m.map_cross_class, slam.numMapPoints(),
      slam.numCrossClassMapPoints());
}

/// Resident memory in MB for the progress line ("?" where /proc is not available).
std::string residentMegabytes() {
  const std::optional<std::uint64_t> bytes = residentSetBytes();
  return bytes ? fmt::format("{:.0f}", static_cast<double>(*bytes) / (1 << 20)) : "?";
}

/// The allocator's in-use and free-but-kept megabytes for the progress line ("" without glibc):
/// RSS growing while "heap" stays flat is fragmentation, not data.
std::string heapMegabytes() {
  const std::optional<HeapUsage> heap = heapUsage();
  if (!heap) return "";
  return fmt::format("  heap {:.0f} MB (free {:.0f})",
                     static_cast<double>(heap->in_use_bytes) / (1 << 20),
                     static_cast<double>(heap->free_bytes) / (1 << 20));
}

/// Prints a progress line at most about once a second: frames, FPS since the start and since the
/// last line, tracking state, map size and resident memory (bench/memory_soak.sh reads it).
class ProgressLine {
 public:
  void update(std::size_t frames, std::size_t total, const tracking::TrackingResult& result,
              const system::System& slam) {
    const auto now = Clock::now();
    if (now - last_ < std::chrono::seconds(1)) return;
    const double recent_fps = static_cast<double>(frames - last_frames_) /
                              std::chrono::duration<double>(now - last_).count();
    last_ = now;
    last_frames_ = frames;
    fmt::print(
        "frame {:5d}/{}  {:6.1f} FPS (now {:5.1f})  {:<11}  keyframes {:4d}  points {:6d}  "
        "RSS {} MB{}\n",
        frames, total, static_cast<double>(frames) / secondsSince(start_), recent_fps,
        tracking::toString(result.state), slam.numKeyFrames(), slam.numMapPoints(),
        residentMegabytes(), heapMegabytes());
    std::fflush(stdout);
  }

 private:
  Clock::time_point start_ = Clock::now();
  Clock::time_point last_ = start_;
  std::size_t last_frames_ = 0;
};

/// Returns the allocator's free pages to the system every 10 s of the run
/// (core/process_memory.h: without it a 30-minute run's RSS grows by freed memory alone).
class PeriodicHeapRelease {
 public:
  void tick() {
    const auto now = Clock::now();
    if (now - last_ < std::chrono::seconds(10)) return;
    last_ = now;
    releaseFreeHeapMemory();
  }

 private:
  Clock::time_point last_ = Clock::now();
};

/// <stem>_keyframes<extension> next to the frame trajectory.
fs::path defaultKeyFramesPath(const fs::path& output) {
  fs::path path = output;
  path.replace_filename(output.stem().string() + "_keyframes" + output.extension().string());
  return path;
}

/// <stem>_config.yaml next to the frame trajectory: the effective options of the run.
fs::path effectiveConfigPath(const fs::path& output) {
  fs::path path = output;
  path.replace_filename(output.stem().string() + "_config.yaml");
  return path;
}

bool sameFile(const fs::path& a, const fs::path& b) {
  return fs::weakly_canonical(fs::absolute(a)) == fs::weakly_canonical(fs::absolute(b));
}

void printAccuracy(const Trajectory& gt, const Trajectory& estimate, eval::AlignmentMode align,
                   const std::string& what = "ATE") {
  if (gt.empty()) return;
  eval::EvaluationOptions options;
  options.align = align;
  options.rpe.unit = eval::DeltaUnit::kFrames;  // short excerpts may not span 1 m
  options.rpe.delta = 1.0;
  try {
    const eval::EvaluationResult r = eval::evaluate(gt, estimate, options);
    fmt::print(
        "{} ({} aligned): rmse {:.4f} m, mean {:.4f} m, max {:.4f} m over {} poses; "
        "ground-truth path {:.2f} m\n",
        what, align == eval::AlignmentMode::kSim3 ? "Sim(3)" : "SE(3)", r.ate_trans.rmse,
        r.ate_trans.mean, r.ate_trans.max, r.pairs, pathLength(gt));
  } catch (const std::exception& e) {
    fmt::print("ATE not available: {}\n", e.what());
  }
}

/// The signal (SIGINT or SIGTERM) that asked the run to stop; 0 while none did.
volatile std::sig_atomic_t g_stop_signal = 0;

/// The first SIGINT / SIGTERM asks the run to stop reading frames; a second one ends the process
/// at once (the default action of the signal).
extern "C" void requestStop(int signal) {
  if (g_stop_signal != 0) {
    std::signal(signal, SIG_DFL);
    std::raise(signal);
    return;
  }
  g_stop_signal = signal;
}

/// Handles SIGINT and SIGTERM for its lifetime (restores the previous handlers).
class StopSignals {
 public:
  StopSignals()
      : previous_int_(std::signal(SIGINT, requestStop)),
        previous_term_(std::signal(SIGTERM, requestStop)) {}
  ~StopSignals() {
    std::signal(SIGINT, previous_int_);
    std::signal(SIGTERM, previous_term_);
  }
  StopSignals(const StopSignals&) = delete;
  StopSignals& operator=(const StopSignals&) = delete;

  static int received() { return g_stop_signal; }
  static const char* name(int signal) { return signal == SIGINT ? "SIGINT" : "SIGTERM"; }

 private:
  using Handler = void (*)(int);
  Handler previous_int_;
  Handler previous_term_;
};

/// The input error that ended a run early: the frame that could not be read and why.
struct InputStop {
  std::size_t frame = 0;  ///< Index of the frame that failed (frames before it were served).
  std::string file;       ///< The file the error names ("" when it names none).
  std::string message;    ///< The error, as InputError::what() gives it.
};

/// Serves the frames of another source until a stop signal arrives or a frame cannot be read (an
/// InputError: a damaged image, a bad row), then ends the sequence: the pipeline finishes the
/// frames it already read, and the run writes their outputs as at a signal.
class StoppableSource final : public io::DatasetSource {
 public:
  explicit StoppableSource(io::DatasetSource& source) : source_(source) {}
  std::optional<sensors::FrameBundle> next() override {
    if (StopSignals::received() != 0 || input_stop_) return std::nullopt;
    try {
      std::optional<sensors::FrameBundle> bundle = source_.next();
      if (bundle) ++served_;
      return bundle;
    } catch (const InputError& e) {
      input_stop_ = InputStop{served_, e.location().file.string(), e.what()};
      return std::nullopt;
    }
  }
  /// Set when a frame could not be read.
  const std::optional<InputStop>& inputStop() const { return input_stop_; }
  std::size_t size() const override { return source_.size(); }
  const sensors::CameraCalibration& camera0() const override { return source_.camera0(); }
  const std::optional<sensors::CameraCalibration>& camera1() const override {
    return source_.camera1();
  }
  const std::optional<sensors::ImuCalibration>& imu() const override { return source_.imu(); }
  Trajectory groundTruth() const override { return source_.groundTruth(); }
  const std::vector<std::string>& warnings() const override { return source_.warnings(); }

 private:
  io::DatasetSource& source_;
  std::size_t served_ = 0;
  std::optional<InputStop> input_stop_;
};

/// Says where an input error stopped the run, before its outputs are written.
void reportInputStop(const InputStop& stop, std::size_t frames, std::size_t total) {
  fmt::print(
      "stopped by an input error at frame {} of {} (0-based index{}): writing the outputs of the "
      "{} frames before it\n",
      stop.frame, total, stop.file.empty() ? "" : ", file " + stop.file, frames);
  std::fflush(stdout);
}

/// One line per IMU gap the tracker met (tracker.imu_max_gap_s), with the dataset times [ns].
void reportImuGap(const tracking::ImuGap& gap, TimeNs frame_t_ns, double max_gap_s) {
  fmt::print(
      "warning: IMU gap of {:.3f} s (no samples between t = {} and {} ns; tracker.imu_max_gap_s "
      "{} s) at frame t = {} ns: predicted without the IMU, no preintegration across the gap, "
      "inertial tracking resumes from the next keyframe\n",
      gap.seconds(), gap.t0_ns, gap.t1_ns, max_gap_s, frame_t_ns);
  std::fflush(stdout);
}

/// The ground-truth pose nearest in time to t_ns (within 20 ms), if any.
std::optional<SE3d> groundTruthAt(const Trajectory& gt, TimeNs t_ns) {
  const auto after = std::lower_bound(gt.begin(), gt.end(), t_ns,
                                      [](const StampedPose& p, TimeNs t) { return p.t_ns < t; });
  std::optional<StampedPose> best;
  for (auto it : {after, after == gt.begin() ? gt.end() : std::prev(after)}) {
    if (it == gt.end()) continue;
    if (!best || std::llabs(it->t_ns - t_ns) < std::llabs(best->t_ns - t_ns)) best = *it;
  }
  if (!best || std::llabs(best->t_ns - t_ns) > 20'000'000) return std::nullopt;
  return best->T_w_x;
}

/// One line per loop (or merge) with its error against the ground truth; returns how many were
/// false and how many could be checked.
std::pair<int, int> printClosures(const char* kind, const std::vector<loop::LoopClosure>& closures,
                                  const Trajectory& gt, const SE3d& T_b_c) {
  int false_closures = 0;
  int checked = 0;
  for (const loop::LoopClosure& l : closures) {
    std::string truth = "no ground truth";
    const std::optional<SE3d> gt_query = groundTruthAt(gt, l.query_t_ns);
    const std::optional<SE3d> gt_match = groundTruthAt(gt, l.match_t_ns);
    if (gt_query && gt_match) {
      const SE3d error = loop::loopError(l, gt_match->inverse() * *gt_query, T_b_c);
      const double angle_deg = rotationAngle(error.rotation()) * 180.0 / M_PI;
      const bool wrong = error.t.norm() > 0.5 || angle_deg > 5.0;
      ++checked;
      false_closures += wrong ? 1 : 0;
      truth = fmt::format("relative pose error {:.3f} m, {:.2f} deg{}", error.t.norm(), angle_deg,
                          wrong ? " (FALSE)" : "");
    }
    const std::string scale =
        l.scale != 1.0 ? fmt::format(" / scale {:.3f} (error at the true length)", l.scale) : "";
    fmt::print(
        "  {}: keyframe at {:.2f} s -> {:.2f} s, {} inliers, correction {:.3f} m / "
        "{:.2f} deg{}; {}\n",
        kind, nsToSeconds(l.query_t_ns), nsToSeconds(l.match_t_ns), l.inliers,
        l.correction.t.norm(), rotationAngle(l.correction.rotation()) * 180.0 / M_PI, scale, truth);
  }
  return {false_closures, checked};
}

/// One line per inertial initialisation stage as the tracker applies it to the current map (a new
/// map starts again from none), and a warning at the end of an inertial run that had none.
class InertialStageLines {
 public:
  InertialStageLines(const system::SystemOptions& options, bool print)
      : options_(options), print_(print && system::usesImu(options.mode)) {}

  void update(const system::System& slam, const tracking::TrackingResult& result) {
    if (!first_t_ns_) first_t_ns_ = result.t_ns;
    const int stages = slam.inertialStages();
    if (stages > stages_) {
      ++applied_;
      if (print_) printStage(stages, slam, result);
    }
    stages_ = stages;
  }

  /// The warning of an inertial run whose maps were never initialised (visual-only poses).
  void warnIfNoneRan() const {
    if (!system::usesImu(options_.mode) || applied_ > 0) return;
    const mapping::InertialMapInitOptions& init = options_.mapping.inertial_init;
    fmt::print(
        "warning: the inertial initialisation never ran (it needs a map of {} keyframes over "
        "{} s): the IMU only predicted the poses, and the map is not gravity-aligned{}\n",
        init.min_keyframes, init.min_duration_s,
        system::isMonocular(options_.mode) ? " nor metric" : "");
  }

 private:
  int totalStages() const {
    return 1 + (options_.mapping.refine_first_s > 0.0 ? 1 : 0) +
           (options_.mapping.refine_second_s > 0.0 ? 1 : 0);
  }

  void printStage(int stage, const system::System& slam,
                  const tracking::TrackingResult& result) const {
    const bool mono = system::isMonocular(options_.mode);
    const std::string what = stage == 1 ? (mono ? "gravity, scale, velocities and IMU biases"
                                                : "gravity, velocities "
                                                  "and IMU biases")
                                        : (stage == 2 ? "first refinement" : "second refinement");
    const std::string scale = mono && result.world_change
                                  ? fmt::format(", map scaled by {:.4f}", result.world_change->s)
                                  : std::string();
    fmt::print(
        "inertial initialisation: stage {} of {} ({}) at frame {}, {:.2f} s into the run; map of "
        "{} keyframes{}\n",
        stage, totalStages(), what, slam.timings().frames - 1,
        nsToSeconds(result.t_ns - *first_t_ns_), slam.numKeyFrames(), scale);
    std::fflush(stdout);
  }

  const system::SystemOptions& options_;
  bool print_;
  int stages_ = 0;
  int applied_ = 0;
  std::optional<TimeNs> first_t_ns_;
};

/// Loops and merges accepted, stage times and, with a ground truth, each one's relative-pose
/// error (the verified relative pose against the true one, loop::loopError): one off by more
/// than 0.5 m or 5 degrees is called false.
void printLoops(const system::System& slam, const Trajectory& gt, const SE3d& T_b_c) {
  if (!slam.options().loop.enabled) {
    fmt::print("loop closing: off\n");
    return;
  }
  const system::LoopSummary loops = slam.loopSummary();
  const auto perKeyFrame = [&](double ms) {
    return loops.keyframes > 0 ? ms / static_cast<double>(loops.keyframes) : 0.0;
  };
  fmt::print(
      "loop closing: {} loops accepted ({} keyframes queried, {} skipped while the loop thread "
      "was busy, {} candidates verified, rejected: "
      "{} too few matches, {} no transform, {} too few inliers, {} tilted, {} beyond the drift; "
      "{} verified loops "
      "not applied); per keyframe: "
      "detection {:.2f} ms, verification {:.2f} ms; pose graph + correction + fusion {:.1f} ms "
      "per loop; index {} descriptors ({:.1f} MB with the graph's links) of {} keyframes, "
      "rebuilt {} times; {} global BAs after loops ({:.0f} ms each), {} dropped\n",
      loops.loops.size(), loops.keyframes, loops.skipped, loops.verifications, loops.rejected[0],
      loops.rejected[1], loops.rejected[2], loops.rejected[3], loops.rejected[4],
      loops.loops_dropped, perKeyFrame(loops.detection_ms), perKeyFrame(loops.verification_ms),
      loops.loops.empty() ? 0.0 : loops.correction_ms / static_cast<double>(loops.loops.size()),
      loops.index_descriptors, static_cast<double>(loops.index_bytes) / 1e6, loops.index_keyframes,
      loops.index_rebuilds, loops.global_bas,
      loops.global_bas > 0 ? loops.global_ba_ms / loops.global_bas : 0.0, loops.global_bas_dropped);
  const auto [false_loops, checked] = printClosures("loop", loops.loops, gt, T_b_c);
  if (checked > 0)
    fmt::print("loop closing: {} of {} loops false against the ground truth\n", false_loops,
               checked);
  fmt::print(
      "map merging: {} atlas maps merged into the active map, {} left unmerged ({} keyframes)\n",
      loops.merges.size(), loops.atlas_maps, loops.atlas_keyframes);
  const auto [false_merges, merges_checked] = printClosures("merge", loops.merges, gt, T_b_c);
  if (merges_checked > 0)
    fmt::print("map merging: {} of {} merges false against the ground truth\n", false_merges,
               merges_checked);
}

class RunCommand : public Command {
 public:
  explicit RunCommand(CLI::App& app) {
    sub_ = app.add_subcommand("run", "Run SLAM over a dataset and write the trajectory");
    addDatasetOptions(*sub_, kind_, path_, /*bags=*/true);
    sub_->add_option("--calibration", bag_calibration_,
                     "rosbag: the calibration of the bag's sensors: a folder of EuRoC-style "
                     "sensor.yaml files (cam0/, cam1/, imu0/; a mav0 folder or the sequence folder "
                     "holding it) or a VINS-Fusion config file (VIODE's calibration.yaml)")
        ->check(CLI::ExistingPath);
    sub_->add_option("--topics", bag_topics_,
                     "rosbag: topic preset or topic file: viode or euroc (/cam0/image_raw, "
                     "/cam1/image_raw, /imu0; ground truth from /odometry when the bag has it), "
                     "tumvi (the same, ground truth from /vrpn_client/raw_transform), openloris "
                     "(/d400/color/image_raw, /d400/accel/sample and /d400/gyro/sample merged at "
                     "the gyroscope's stamps; monocular), or a YAML file with keys cam0, cam1, imu "
                     "or accel and gyro, ground_truth")
        ->capture_default_str();
    sub_->add_option("--ground-truth", bag_ground_truth_,
                     "rosbag: ground-truth file of the body (TUM, EuRoC CSV, OpenLORIS), instead "
                     "of the bag's ground-truth topic")
        ->check(CLI::ExistingFile);
    sub_->add_option("--mode", mode_,
                     "Sensor mode: stereo | stereo-inertial | mono | mono-inertial (default: what "
                     "the dataset holds: two cameras and an IMU -> stereo-inertial, two cameras "
                     "-> stereo, one camera and an IMU -> mono-inertial, one camera -> mono)")
        ->check(CLI::IsMember({"stereo", "stereo-inertial", "mono", "mono-inertial"}));
    sub_->add_option("--output", output_, "Trajectory file to write")->required();
    sub_->add_option("--format", format_, "Trajectory format")
        ->check(CLI::IsMember({"tum", "euroc", "kitti"}))
        ->capture_default_str();
    sub_->add_option("--max-frames", max_frames_, "Process at most this many frames (0 = all)")
        ->capture_default_str();
    sub_->add_option("--config", config_, "YAML options file (configs/*.yaml)")
        ->check(CLI::ExistingFile);
    sub_->add_option("--keyframes", keyframes_,
                     "Keyframe trajectory file (same --format; default: <output "
                     "stem>_keyframes<output extension> beside --output)");
    sub_->add_option("--online-trajectory", online_,
                     "Also write each frame's pose as it was tracked at that frame (causal; "
                     "--output holds each frame relative to its keyframe after the keyframes' "
                     "later corrections)");
    sub_->add_option("--features", features_,
                     "Feature extractor: orb | xfeat | superpoint | alike (overrides "
                     "features.type)")
        ->check(CLI::IsMember({"orb", "xfeat", "superpoint", "alike"}));
    sub_->add_option("--model", model_,
                     "ONNX model of a learned extractor (overrides features.model; a bare name is "
                     "looked up in $SUPERDYNA_MODEL_DIR, then models/)");
    sub_->add_option("--frame-log", frame_log_,
                     "Also write a CSV row per frame: index, tracking state, map matches, pose "
                     "inliers, distance of the tracked from the predicted position [m], tracked "
                     "from the reference keyframe (1/0), keyframe (1/0), how it came back after "
                     "a failure");
    sub_->add_option("--dynamic", dynamic_,
                     "Moving-object handling (overrides dynamic.mode): off (robust kernels "
                     "only), semantic (drop every movable object) or semantic-geometric (drop "
                     "the objects the IMU-predicted motion test finds moving); needs labelled "
                     "keypoints (--instance-masks or --segmenter)")
        ->check(CLI::IsMember({"off", "semantic", "semantic-geometric"}));
    sub_->add_option("--stats", stats_,
                     "Also write the run's numbers as JSON: frames, wall time, FPS, lost frames, "
                     "map resets, keyframes, mean ms per stage, CPU time per thread (superdyna "
                     "sweep reads it)");
    sub_->add_option("--dynamic-log", dynamic_log_,
                     "Also write a CSV row per movable object per frame: "
                     "t_ns,instance_id,class,pairs,tested,max_distance_px,threshold_px,decision,"
                     "keypoints,dropped");
    sub_->add_option("--segmenter", segmenter_,
                     "Instance segmentation labelling the keypoints: none | dataset | yolo | "
                     "maskrcnn | sam (overrides semantics.segmenter)")
        ->check(CLI::IsMember({"none", "dataset", "yolo", "maskrcnn", "sam"}));
    sub_->add_flag("--instance-masks", instance_masks_,
                   "Short for --segmenter dataset with semantics.dataset_format masks: label "
                   "keypoints with the sequence's instance masks (simulated sequences: "
                   "mav0/camN/mask/ and instances.csv)");
    sub_->add_option("--segment-every", segment_every_,
                     "Segment one frame in N; the frames between get the masks of the frame "
                     "before them moved with their keypoint matches (overrides "
                     "semantics.every_n_frames)")
        ->check(CLI::PositiveNumber);
    sub_->add_option("--overlay", overlay_dir_,
                     "Write overlay PNGs into this folder: left image, instance masks, keypoints "
                     "coloured by class; with the moving-object test on, every object it decided "
                     "on (moving: filled mask, red outline; static: green outline; unverified: "
                     "dashed yellow outline with the reason), the keypoints kept (green) or "
                     "dropped (red) and a legend");
    sub_->add_option("--overlay-every", overlay_every_, "Overlay every N-th frame")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub_->add_option("--loop-closing", loop_closing_,
                     "Loop closing (overrides loop.enabled): on | off. SE(3) loops in stereo and "
                     "inertial maps (mono-inertial once its inertial stages have run), Sim(3) "
                     "loops in mono maps; with it, a map left after a tracking failure is kept "
                     "and merged into the new one when it sees its places again")
        ->check(CLI::IsMember({"on", "off"}));
    sub_->add_option("--save-map", save_map_,
                     "Write the map at the end of the run to this file (versioned binary map "
                     "file: keyframes, points, descriptors, covisibility, IMU states)");
    sub_->add_option("--load-map", load_map_,
                     "Track against the map of this file (made by --save-map with the same "
                     "features, mode and rig); needs --localization-only")
        ->check(CLI::ExistingFile);
    sub_->add_flag("--localization-only", localization_only_,
                   "With --load-map: locate the first frame in the loaded map and track against "
                   "it without changing it (no keyframes, points, bundle adjustment or loop "
                   "closing)");
    sub_->add_flag("--print-config", print_config_,
                   "Print the effective options (they are always written to <output "
                   "stem>_config.yaml beside --output)");
    sub_->add_flag("--quiet", quiet_,
                   "Print only warnings, errors and the final summary (no progress lines)");
    sub_->add_flag(
        "--deterministic", deterministic_,
        "Sequential, single-threaded run: bit-identical output for the same input "
        "(default: concurrent front end, tracking, local mapping and loop closing threads)");
  }

  CLI::App* subcommand() const override { return sub_; }

  /// Prints unless --quiet (warnings and the final summary are printed either way).
  template <typename... Args>
  void inform(fmt::format_string<Args...> format, Args&&... args) const {
    if (!quiet_) fmt::print(format, std::forward<Args>(args)...);
  }

  /// The sensors of the dataset (--dataset, --path, --topics): "two cameras and an IMU", ...
  std::pair<bool, bool> datasetSensors() const {
    if (kind_ == "kitti") return {io::KittiDataset::open(path_).isStereo(), false};
#ifdef SUPERDYNA_WITH_ROSBAG
    if (kind_ == "rosbag") {
      const bag::BagTopics topics = bag::bagTopics(bag_topics_);
      return {!topics.cam1.empty(), !topics.imu.empty() || !topics.gyro.empty()};
    }
#endif
    if (kind_ == "rosbag") return {true, true};  // openSource says why it cannot be read
    const io::EurocDataset dataset = io::EurocDataset::open(path_);
    return {dataset.isStereo(), dataset.imuCalibration().has_value()};
  }

  /// --mode, or what the dataset holds (said on the output).
  system::SensorMode sensorMode() const {
    if (mode_) return system::parseSensorMode(*mode_);
    const auto [stereo, imu] = datasetSensors();
    const system::SensorMode mode =
        stereo ? (imu ? system::SensorMode::kStereoInertial : system::SensorMode::kStereo)
               : (imu ? system::SensorMode::kMonoInertial : system::SensorMode::kMono);
    inform("mode: {} (the dataset has {}{}; --mode chooses another)\n", system::toString(mode),
           stereo ? "two cameras" : "one camera", imu ? " and an IMU" : "");
    return mode;
  }

  /// The dataset folder, or the bag with its calibration.
  std::unique_ptr<io::DatasetSource> openSource(const io::DatasetSourceOptions& options) const {
    if (kind_ != "rosbag") return io::openDataset(io::parseDatasetKind(kind_), path_, options);
#ifdef SUPERDYNA_WITH_ROSBAG
    if (!bag_calibration_) {
      throw OptionError("--calibration",
                        "--dataset rosbag needs the folder of the bag's "
                        "sensor.yaml files (bags carry no calibration)");
    }
    return bag::openBagSource(path_, *bag_calibration_, bag::bagTopics(bag_topics_), options,
                              bag_ground_truth_);
#else
    throw OptionError("--dataset",
                      "this build has no ROS bag support: install Debian's librosbag-storage-dev, "
                      "libsensor-msgs-dev and libnav-msgs-dev and build again (scripts/setup.sh)");
#endif
  }

  /// The segmenter of the options; for a bag, the dataset backend reads its segmentation topics.
  std::unique_ptr<semantics::Segmenter> openSegmenter(
      const semantics::SegmenterOptions& options) const {
#ifdef SUPERDYNA_WITH_ROSBAG
    if (kind_ == "rosbag") return bag::makeBagSegmenter(options, path_, *bag_calibration_);
#endif
    return semantics::makeSegmenter(options, path_);
  }

  /// The dataset is the user's data: never write a result over one of its files.
  void refuseOutputInsideDataset(const fs::path& file, const std::string& option) const {
    const fs::path output = fs::weakly_canonical(fs::absolute(file));
    const fs::path dataset = fs::weakly_canonical(fs::absolute(path_));
    const auto [end, unused] =
        std::mismatch(dataset.begin(), dataset.end(), output.begin(), output.end());
    if (end == dataset.end() && fs::exists(output)) {
      throw OptionError(option, fmt::format("'{}' is a file of the dataset; refusing to "
                                            "overwrite it",
                                            file.string()));
    }
  }

  void refuseOnlineTrajectoryPath(const fs::path& path, const fs::path& keyframes_path) const {
    refuseOutputInsideDataset(path, "--online-trajectory");
    for (const fs::path& other : {output_, keyframes_path}) {
      if (sameFile(path, other)) {
        throw OptionError("--online-trajectory",
                          fmt::format("'{}' is also another output of the run", path.string()));
      }
    }
  }

  fs::path keyFramesPath() const {
    const fs::path path = keyframes_ ? *keyframes_ : defaultKeyFramesPath(output_);
    if (sameFile(path, output_)) {
      throw OptionError("--keyframes",
                        fmt::format("'{}' is also the --output file", path.string()));
    }
    return path;
  }

  /// Where the effective options go: beside --output, never over the dataset, the --config file
  /// read or another output of the run.
  fs::path configPath(const fs::path& keyframes_path) const {
    const fs::path path = effectiveConfigPath(output_);
    refuseOutputInsideDataset(path, "--output");
    if (config_) requireDistinctOutput(path, {*config_}, "--output");
    const auto refuseSame = [&](const fs::path& other, const std::string& option) {
      if (!sameFile(path, other)) return;
      throw OptionError(option, fmt::format("'{}' is also the effective options file of the run "
                                            "(<output stem>_config.yaml)",
                                            other.string()));
    };
    refuseSame(keyframes_path, "--keyframes");
    if (online_) refuseSame(*online_, "--online-trajectory");
    if (frame_log_) refuseSame(*frame_log_, "--frame-log");
    if (dynamic_log_) refuseSame(*dynamic_log_, "--dynamic-log");
    return path;
  }

  /// No output of the run may replace the --config file it reads.
  void refuseOutputOntoConfig(const fs::path& keyframes_path) const {
    if (!config_) return;
    requireDistinctOutput(output_, {*config_}, "--output");
    requireDistinctOutput(keyframes_path, {*config_}, "--keyframes");
    if (frame_log_) requireDistinctOutput(*frame_log_, {*config_}, "--frame-log");
    if (dynamic_log_) requireDistinctOutput(*dynamic_log_, {*config_}, "--dynamic-log");
  }

  /// --stats is written beside the other outputs, never over one of them or an input.
  void refuseStatsPath(const fs::path& keyframes_path, const fs::path& config_path) const {
    refuseOutputInsideDataset(*stats_, "--stats");
    std::vector<fs::path> others = {output_, keyframes_path, config_path};
    for (const auto& other : {config_, online_, frame_log_, dynamic_log_, save_map_, load_map_}) {
      if (other) others.push_back(*other);
    }
    requireDistinctOutput(*stats_, others, "--stats");
  }

  /// --load-map / --localization-only / --save-map go together as documented; the map file is
  /// never written over an input or another output.
  void checkMapOptions(const fs::path& keyframes_path, const fs::path& config_path) const {
    if (localization_only_ && !load_map_) {
      throw OptionError("--localization-only", "needs a map to track against: add --load-map");
    }
    if (load_map_ && !localization_only_) {
      throw OptionError("--load-map",
                        "continuing to map a loaded map is not supported yet: add "
                        "--localization-only");
    }
    if (localization_only_ && loop_closing_ == "on") {
      throw OptionError("--loop-closing", "--localization-only never changes the map");
    }
    if (!save_map_) return;
    refuseOutputInsideDataset(*save_map_, "--save-map");
    std::vector<fs::path> others = {output_, keyframes_path, config_path};
    if (config_) others.push_back(*config_);
    if (load_map_) others.push_back(*load_map_);
    if (online_) others.push_back(*online_);
    if (frame_log_) others.push_back(*frame_log_);
    if (dynamic_log_) others.push_back(*dynamic_log_);
    for (const fs::path& other : others) {
      if (sameFile(*save_map_, other)) {
        throw OptionError("--save-map", fmt::format("'{}' is also an input or another output of "
                                                    "the run",
                                                    save_map_->string()));
      }
    }
  }

  void saveMap(const system::System& slam) const {
    const std::optional<map::MapFile> file = slam.mapFile();
    if (!file) throw InputError(InputLocation(*save_map_), "no map to save: nothing was mapped");
    map::writeMapFile(*save_map_, *file);
    fmt::print("map saved to {}: {} keyframes, {} points, inertial stages {}, {} bytes\n",
               save_map_->string(), file->contents.keyframes.size(), file->contents.points.size(),
               file->inertial_stages, fs::file_size(*save_map_));
  }

  int run() override {
    refuseOutputInsideDataset(output_, "--output");
    const fs::path keyframes_path = keyFramesPath();
    refuseOutputInsideDataset(keyframes_path, "--keyframes");
    if (frame_log_) refuseOutputInsideDataset(*frame_log_, "--frame-log");
    if (online_) refuseOnlineTrajectoryPath(*online_, keyframes_path);
    if (dynamic_log_) refuseOutputInsideDataset(*dynamic_log_, "--dynamic-log");
    const fs::path config_path = configPath(keyframes_path);
    refuseOutputOntoConfig(keyframes_path);
    checkMapOptions(keyframes_path, config_path);
    if (stats_) refuseStatsPath(keyframes_path, config_path);
    system::SystemOptions options;
    if (config_) options = system::loadSystemOptions(*config_);
    options.mode = sensorMode();
    if (features_)
      options.front_end.features.type = features::parseFeatureType(*features_, "--features");
    if (model_) {
      if (options.front_end.features.type == features::FeatureType::kOrb) {
        throw OptionError("--model", "ORB has no model; choose --features xfeat or superpoint");
      }
      options.front_end.features.model = *model_;
    }
    if (segmenter_) options.semantics.segmenter = *segmenter_;
    if (segment_every_) options.semantics.every_n_frames = *segment_every_;
    if (instance_masks_) {
      if (segmenter_ && *segmenter_ != "dataset") {
        throw OptionError("--instance-masks",
                          "is --segmenter dataset; it contradicts --segmenter " + *segmenter_);
      }
      options.semantics.segmenter = "dataset";
      options.semantics.dataset_format = "masks";
    }
    if (dynamic_) options.tracker.dynamic.mode = dynamic::parseDynamicMode(*dynamic_, "--dynamic");
    if (!options.semantics.idsNameObjects() &&
        options.tracker.dynamic.mode != dynamic::DynamicMode::kOff &&
        options.tracker.dynamic.cull_points_by_instance) {
      // Network segmenters (and per-image id PNGs) renumber their instances every frame: a map
      // point's instance id says nothing about which object it lies on later.
      options.tracker.dynamic.cull_points_by_instance = false;
      inform("dynamic.cull_points_by_instance: off (segmenter {} does not keep instance ids)\n",
             options.semantics.segmenter);
    }
    if (options.tracker.dynamic.mode != dynamic::DynamicMode::kOff &&
        options.semantics.segmenter == "none") {
      throw OptionError(dynamic_ ? "--dynamic" : "dynamic.mode",
                        fmt::format("mode {} needs keypoints labelled by a segmenter: add "
                                    "--instance-masks or --segmenter",
                                    dynamic::toString(options.tracker.dynamic.mode)));
    }
    if (loop_closing_) {
      options.loop.enabled = *loop_closing_ == "on";
    }
    if (localization_only_) options.loop.enabled = false;
    options.deterministic = deterministic_;
    // Read before the dataset: a damaged map file stops the run at once.
    std::optional<map::MapFile> loaded;
    if (load_map_) loaded = map::readMapFile(*load_map_);
    const io::TrajectoryFormat format = io::parseTrajectoryFormat(format_);

    io::DatasetSourceOptions source_options;
    source_options.stereo = !system::isMonocular(options.mode);
    source_options.inertial = system::usesImu(options.mode);
    source_options.max_frames = max_frames_;
    const std::unique_ptr<io::DatasetSource> source = openSource(source_options);
    for (const std::string& warning : source->warnings())
      fmt::print("warning: {}\n", warning);
    std::unique_ptr<semantics::Segmenter> segmenter = openSegmenter(options.semantics);
    const std::string segmentation = segmenter ? segmenter->description() : "none";
    system::System slam(options, source->camera0(), source->camera1(), source->imu(),
                        std::move(segmenter));
    if (loaded) {
      slam.localizeIn(*loaded, *load_map_);
      inform("localization-only against {}: {} keyframes, {} points ({} features, {})\n",
             load_map_->string(), loaded->contents.keyframes.size(), loaded->contents.points.size(),
             loaded->identity.feature_type, loaded->identity.sensor_mode);
      loaded.reset();
    }
    std::optional<OverlayWriter> overlay;
    if (overlay_dir_) {
      refuseOutputInsideDataset(*overlay_dir_, "--overlay");
      overlay.emplace(*overlay_dir_, overlay_every_,
                      options.tracker.dynamic.mode != dynamic::DynamicMode::kOff ||
                          options.tracker.dynamic.geometric,
                      options.tracker.dynamic);
      slam.setFrontEndCallback(
          [&overlay](const sensors::FrameBundle& bundle, const tracking::Frame& frame) {
            overlay->remember(bundle, frame);
          });
    }

    inform("running {} SLAM with {} features ({}) on {} ({} frames)\n",
           system::toString(options.mode), features::toString(options.front_end.features.type),
           options.deterministic ? "deterministic" : "concurrent", path_.string(), source->size());
    inform("segmentation: {}\n", segmentation);
    system::writeSystemOptions(config_path, slam.options());
    if (print_config_) {
      fmt::print("effective options (written to {}):\n{}", config_path.string(),
                 system::formatSystemOptions(slam.options()));
    } else {
      inform("effective options written to {} (--print-config prints them)\n",
             config_path.string());
    }
    InertialStageLines inertial_stages(slam.options(), !quiet_);
    ProgressLine progress;
    PeriodicHeapRelease heap_release;
    std::optional<system::FrameLog> frame_log;
    if (frame_log_) frame_log.emplace(*frame_log_, "--frame-log");
    std::optional<system::DynamicLog> dynamic_log;
    if (dynamic_log_) dynamic_log.emplace(*dynamic_log_, "--dynamic-log");
    std::size_t imu_gaps = 0;
    const StopSignals stop_signals;
    StoppableSource stoppable(*source);
    slam.run(stoppable, [&](const tracking::TrackingResult& result) {
      if (result.imu_gap) {
        ++imu_gaps;
        reportImuGap(*result.imu_gap, result.t_ns, slam.options().tracker.imu_max_gap_s);
      }
      if (frame_log) frame_log->write(slam.timings().frames - 1, result);
      if (dynamic_log) dynamic_log->write(result);
      if (overlay) overlay->write(result);
      inertial_stages.update(slam, result);
      if (!quiet_) progress.update(slam.timings().frames, source->size(), result, slam);
      heap_release.tick();
    });
    const int stopped_by = StopSignals::received();
    const std::optional<InputStop>& input_stop = stoppable.inputStop();
    if (stopped_by != 0) {
      fmt::print("stopped by {} after {} of {} frames: writing the outputs of the frames so far\n",
                 StopSignals::name(stopped_by), slam.timings().frames, source->size());
    } else if (input_stop) {
      reportInputStop(*input_stop, slam.timings().frames, source->size());
    }
    const system::TimingSummary& t = slam.timings();
    const Trajectory keyframes = slam.keyFrameTrajectory();
    const Trajectory trajectory = slam.trajectory();
    io::writeTrajectory(output_, trajectory, format);
    io::writeTrajectory(keyframes_path, keyframes, format);
    if (online_) io::writeTrajectory(*online_, slam.onlineTrajectory(), format);
    if (save_map_) saveMap(slam);
    if (stats_) writeJson(*stats_, runStatsJson(slam, stopped_by != 0));
    fmt::print(
        "{} frames in {:.2f} s ({:.1f} FPS); lost frames {}, map resets {}, relocalisations {}; "
        "wrote {} and {} ({} keyframes)\n",
        t.frames, t.wall_s, t.framesPerSecond(), slam.lostFrames(), slam.resets(),
        slam.relocalizations(), output_.string(), keyframes_path.string(), keyframes.size());
    if (imu_gaps > 0) fmt::print("IMU gaps bridged without preintegration: {}\n", imu_gaps);
    inertial_stages.warnIfNoneRan();
    fmt::print("frames tracked from the reference keyframe without a prediction: {}\n",
               slam.referenceTrackedFrames());
    if (slam.reanchors() > 0) {
      fmt::print("keyframes inserted at the IMU-predicted pose after a failure: {}\n",
                 slam.reanchors());
    }
    if (load_map_) {
      fmt::print(
          "localization-only: {} frames not located in the loaded map (not in the "
          "trajectory)\n",
          slam.localizingFrames());
    }
    if (system::isMonocular(options.mode)) {
      fmt::print("monocular: {} frames spent initialising maps (not in the trajectory)\n",
                 slam.initializingFrames());
    }
    printTimings(slam.options(), t);
    if (segmentation != "none") printSegmentation(t);
    printMatchCounts(slam);
    printLoops(slam, source->groundTruth(), source->camera0().T_b_c);
    printAccuracy(source->groundTruth(), slam.onlineTrajectory(), eval::AlignmentMode::kSE3,
                  "ATE of the poses as tracked");
    printAccuracy(source->groundTruth(), trajectory, eval::AlignmentMode::kSE3);
    // Visual-only monocular trajectories have no metric scale.
    if (options.mode == system::SensorMode::kMono) {
      printAccuracy(source->groundTruth(), trajectory, eval::AlignmentMode::kSim3);
    }
    if (input_stop) {
      // The error last, where the user looks for it; the outputs of the frames before it are
      // written.
      throw InputError(input_stop->message);
    }
    return stopped_by == 0 ? 0 : 128 + stopped_by;  // the shell's code for a signal's end
  }

 private:
  CLI::App* sub_ = nullptr;
  std::string kind_ = "euroc";
  std::optional<fs::path> bag_calibration_;
  fs::path bag_ground_truth_;
  std::string bag_topics_ = "viode";
  fs::path path_;
  std::optional<std::string> mode_;
  fs::path output_;
  std::optional<fs::path> keyframes_;
  std::optional<fs::path> frame_log_;
  std::optional<fs::path> online_;
  std::optional<fs::path> dynamic_log_;
  std::optional<fs::path> stats_;
  std::optional<std::string> dynamic_;
  std::string format_ = "tum";
  std::size_t max_frames_ = 0;
  std::optional<fs::path> config_;
  std::optional<std::string> features_;
  std::optional<std::string> model_;
  std::optional<std::string> segmenter_;
  std::optional<int> segment_every_;
  bool instance_masks_ = false;
  std::optional<fs::path> overlay_dir_;
  int overlay_every_ = 10;
  std::optional<std::string> loop_closing_;
  bool deterministic_ = false;
  bool print_config_ = false;
  bool quiet_ = false;
  std::optional<fs::path> save_map_;
  std::optional<fs::path> load_map_;
  bool localization_only_ = false;
};

}  // namespace

std::unique_ptr<Command> makeRunCommand(CLI::App& app) {
  return std::make_unique<RunCommand>(app);
}

}  // namespace superdyna::apps
