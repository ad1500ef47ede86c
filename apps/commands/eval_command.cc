#include "commands/eval_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <fstream>
#include <optional>
#include <string>
#include <vector>

#include "commands/output_files.h"
#include "superdyna/core/error.h"
#include "superdyna/eval/evaluate.h"
#include "superdyna/eval/multi_run.h"
#include "superdyna/eval/plot.h"
#include "superdyna/eval/report_json.h"
#include "superdyna/eval/report_table.h"
#include "superdyna/io/calibration.h"
#include "superdyna/io/trajectory_io.h"

namespace superdyna::apps {

namespace fs = std::filesystem;

namespace {

struct EvalArguments {
  fs::path gt;
  std::vector<fs::path> estimates;
  std::string gt_format = "auto";
  std::string est_format = "auto";
  std::optional<fs::path> gt_times;
  std::optional<fs::path> est_times;
  std::optional<int> gt_segment;
  std::string align = "se3";
  int align_first = 0;
  double max_diff_s = 0.01;
  double offset_s = 0.0;
  double rpe_delta = 1.0;
  std::string rpe_unit = "m";
  std::optional<fs::path> json;
  std::optional<fs::path> plot;
  std::string plot_plane = "auto";
  std::string plot_span = "estimate";
  std::optional<fs::path> alignment;       ///< A report whose alignment is applied unchanged.
  std::optional<fs::path> alignment_from;  ///< Another run's estimate to align ...
  std::optional<fs::path> alignment_gt;    ///< ... to its ground truth.
  std::optional<fs::path> camera_frame;    ///< A EuRoC sensor.yaml: evaluate that sensor's pose.
};

class EvalCommand : public Command {
 public:
  explicit EvalCommand(CLI::App& app) {
    sub_ = app.add_subcommand("eval",
                              "Absolute and relative trajectory error (ATE, RPE) of one or "
                              "more estimates against ground truth");
    sub_->add_option("--gt", args_.gt, "Ground-truth trajectory (TUM, EuRoC CSV or KITTI)")
        ->required()
        ->check(CLI::ExistingFile);
    sub_->add_option("--est", args_.estimates,
                     "Estimated trajectory; repeat for several runs of one sequence (N-run "
                     "statistics: median, mean ± 95% CI)")
        ->required()
        ->check(CLI::ExistingFile);
    sub_->add_option("--gt-format", args_.gt_format, "Format of --gt")
        ->check(CLI::IsMember({"auto", "tum", "euroc", "kitti"}))
        ->capture_default_str();
    sub_->add_option("--est-format", args_.est_format, "Format of every --est")
        ->check(CLI::IsMember({"auto", "tum", "euroc", "kitti"}))
        ->capture_default_str();
    sub_->add_option("--gt-times", args_.gt_times,
                     "KITTI times file for --gt (default: 10 Hz from 0 s)")
        ->check(CLI::ExistingFile);
    sub_->add_option("--est-times", args_.est_times, "KITTI times file for every --est")
        ->check(CLI::ExistingFile);
    sub_->add_option("--gt-segment", args_.gt_segment,
                     "Use only the 'seq: N' block of a multi-recording TUM file (OpenLORIS)");
    sub_->add_option("--align", args_.align,
                     "Alignment before ATE: none, se3 (rigid) or sim3 (with scale, for mono)")
        ->check(CLI::IsMember({"none", "se3", "sim3"}))
        ->capture_default_str();
    sub_->add_option("--align-first", args_.align_first,
                     "Align on the first N associated poses only (0 = all)")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
    sub_->add_option("--max-diff", args_.max_diff_s,
                     "Largest time difference of an associated pose pair [s]")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub_->add_option("--offset", args_.offset_s, "Added to the estimate's timestamps [s]")
        ->capture_default_str();
    sub_->add_option("--rpe-delta", args_.rpe_delta,
                     "RPE pair separation: metres of ground-truth path, or frames (a path "
                     "shorter than it gets the ATE and a warning instead of an RPE)")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub_->add_option("--rpe-unit", args_.rpe_unit,
                     "Unit of --rpe-delta: m (errors in m/m and deg/m) or frames (m and deg)")
        ->check(CLI::IsMember({"m", "frames"}))
        ->capture_default_str();
    sub_->add_option("--json", args_.json, "Write the results as JSON to this file");
    sub_->add_option("--plot", args_.plot,
                     "Write a top-view plot (ground truth and aligned estimates), .svg or .png");
    sub_->add_option("--plot-plane", args_.plot_plane,
                     "Plane of the top view: xy, xz, yz, or auto (the ground truth's two axes "
                     "of largest extent: x-y for EuRoC and TUM, x-z for KITTI's camera frame)")
        ->check(CLI::IsMember({"auto", "xy", "xz", "yz"}))
        ->capture_default_str();
    sub_->add_option("--plot-span", args_.plot_span,
                     "Ground truth the plot shows: estimate (the estimates' time span, from their "
                     "first to their last associated pose) or all")
        ->check(CLI::IsMember({"estimate", "all"}))
        ->capture_default_str();
    auto* given = sub_->add_option(
        "--alignment", args_.alignment,
        "Apply this alignment unchanged instead of estimating one: the 'alignment' (R, t, s) of "
        "a report written by eval --json (e.g. of a run in the same world)");
    given->check(CLI::ExistingFile);
    auto* from = sub_->add_option("--alignment-from", args_.alignment_from,
                                  "Borrow the alignment of another run: the --align alignment "
                                  "of this estimate to --alignment-gt, applied unchanged");
    from->check(CLI::ExistingFile)->excludes(given);
    sub_->add_option("--alignment-gt", args_.alignment_gt,
                     "Ground truth of the --alignment-from estimate (same formats as --gt)")
        ->check(CLI::ExistingFile)
        ->excludes(given);
    sub_->add_option("--camera-frame", args_.camera_frame,
                     "Evaluate the pose of this camera instead of the body: a EuRoC sensor.yaml "
                     "(e.g. mav0/cam0/sensor.yaml) whose T_BS moves every pose of the ground "
                     "truth and the estimates. For visual mono runs: their map places the body "
                     "through the metric camera-body lever arm in the map's own unit")
        ->check(CLI::ExistingFile);
    sub_->footer(
        "Formats are detected from the content unless given. TUM: 't tx ty tz qx qy qz qw' (s); "
        "EuRoC: 't_ns,px,py,pz,qw,qx,qy,qz,...'; KITTI: 12 numbers a line (3x4 pose).");
  }

  CLI::App* subcommand() const override { return sub_; }

  int run() override {
    std::vector<fs::path> inputs = args_.estimates;
    inputs.push_back(args_.gt);
    for (const auto& file : {args_.alignment, args_.alignment_from, args_.alignment_gt})
      if (file) inputs.push_back(*file);
    if (args_.json) requireDistinctOutput(*args_.json, inputs, "--json");
    if (args_.plot) requireDistinctOutput(*args_.plot, inputs, "--plot");

    eval::EvaluationOptions options = evaluationOptions();
    options.validate();
    options.given_alignment = givenAlignment(options);
    const Trajectory gt = readGroundTruth();
    std::vector<Trajectory> estimates;
    std::vector<std::string> names;
    for (const fs::path& file : args_.estimates) {
      estimates.push_back(readEstimate(file));
      names.push_back(file.filename().string());
    }
    if (estimates.size() == 1) {
      reportSingle(gt, eval::evaluate(gt, estimates.front(), options), names.front());
    } else {
      reportMultiple(gt, eval::evaluateRuns(gt, estimates, options, names));
    }
    return 0;
  }

 private:
  eval::EvaluationOptions evaluationOptions() const {
    eval::EvaluationOptions options;
    options.align = eval::parseAlignmentMode(args_.align);
    options.align_first_n = args_.align_first;
    options.association.max_diff_ns = secondsToNs(args_.max_diff_s);
    options.association.offset_ns = secondsToNs(args_.offset_s);
    options.rpe.delta = args_.rpe_delta;
    options.rpe.unit =
        args_.rpe_unit == "frames" ? eval::DeltaUnit::kFrames : eval::DeltaUnit::kMeters;
    options.require_rpe = false;  // a path shorter than the delta still has an ATE
    return options;
  }

  /// The alignment of --alignment, or the one of --alignment-from to --alignment-gt.
  std::optional<Sim3d> givenAlignment(const eval::EvaluationOptions& options) const {
    if (args_.alignment_from.has_value() != args_.alignment_gt.has_value()) {
      throw OptionError(args_.alignment_from ? "--alignment-from" : "--alignment-gt",
                        "--alignment-from and --alignment-gt go together");
    }
    if ((args_.alignment || args_.alignment_from) && args_.align_first > 0) {
      throw OptionError("--align-first", "a given alignment is not estimated on any poses");
    }
    if (args_.alignment) {
      const Sim3d alignment = eval::readAlignmentJson(*args_.alignment);
      fmt::print("alignment from {} (scale {:.6f}), applied unchanged\n", args_.alignment->string(),
                 alignment.s);
      return alignment;
    }
    if (!args_.alignment_from) return std::nullopt;
    const eval::EvaluationResult other = eval::evaluate(
        readTrajectory(*args_.alignment_gt, args_.gt_format, args_.gt_times, args_.gt_segment),
        readEstimate(*args_.alignment_from), options);
    fmt::print("alignment ({}) of {} to {}: ATE rmse {:.6f} m over {} pairs; applied unchanged\n",
               eval::toString(options.align), args_.alignment_from->string(),
               args_.alignment_gt->string(), other.ate_trans.rmse, other.pairs);
    return other.alignment;
  }

  Trajectory readTrajectory(const fs::path& file, const std::string& format,
                            const std::optional<fs::path>& times,
                            const std::optional<int>& segment) const {
    io::TrajectoryReadOptions read;
    read.format = io::parseTrajectoryFormat(format);
    read.kitti_times = times;
    read.segment = segment;
    return inEvaluatedFrame(io::readTrajectory(file, read));
  }

  Trajectory readGroundTruth() const {
    return readTrajectory(args_.gt, args_.gt_format, args_.gt_times, args_.gt_segment);
  }

  Trajectory readEstimate(const fs::path& file) const {
    return readTrajectory(file, args_.est_format, args_.est_times, std::nullopt);
  }

  /// The poses of --camera-frame's camera (T_w_b * T_b_c), or the trajectory as it is.
  Trajectory inEvaluatedFrame(Trajectory trajectory) const {
    if (!args_.camera_frame) return trajectory;
    const SE3d T_b_c = io::readCameraCalibration(*args_.camera_frame).T_b_c;
    for (StampedPose& pose : trajectory)
      pose.T_w_x = pose.T_w_x * T_b_c;
    return trajectory;
  }

  eval::PlotOptions plotOptions() const {
    eval::PlotOptions options;
    options.plane = eval::parsePlotPlane(args_.plot_plane);
    return options;
  }

  /// The RPE left out of a run (its path is shorter than the delta) and how to get one.
  static void warnIfRpeMissing(const eval::EvaluationResult& result, const std::string& name) {
    if (result.rpe_missing.empty()) return;
    spdlog::warn(
        "{}: {}: the RPE is left out; use a --rpe-delta shorter than that path, or --rpe-unit "
        "frames",
        name, result.rpe_missing);
  }

  /// The --plot file: the ground truth of --plot-span and the aligned estimates.
  void writePlot(const Trajectory& gt, const std::vector<const eval::EvaluationResult*>& results,
                 const std::vector<eval::PlotSeries>& estimates) const {
    const eval::PlotSpan span = eval::parsePlotSpan(args_.plot_span);
    const Trajectory shown = eval::plottedGroundTruth(gt, results, span);
    eval::writeTopViewPlot(*args_.plot, eval::toPlotSeries(shown, "ground truth"), estimates,
                           plotOptions());
    const auto since_start = [&](const StampedPose& pose) {
      return nsToSeconds(pose.t_ns - gt.front().t_ns);
    };
    spdlog::info("plot written to {}: ground truth from {:.2f} s to {:.2f} s of its {:.2f} s{}",
                 args_.plot->string(), since_start(shown.front()), since_start(shown.back()),
                 since_start(gt.back()),
                 span == eval::PlotSpan::kEstimate
                     ? " (the estimate's time span; --plot-span all shows all of it)"
                     : "");
  }

  /// An alignment whose rotation the path does not determine (its ATE rot means nothing).
  static void warnIfRotationUndetermined(const eval::EvaluationResult& result,
                                         const std::string& name) {
    if (!result.alignmentRotationUndetermined()) return;
    spdlog::warn(
        "{}: the path does not determine the alignment's rotation: over {} pairs the ATE "
        "({:.4f} m) is not small against the path's spread across its main direction, so the "
        "rotation is uncertain by about {:.0f} deg; ATE rot and the aligned orientations are "
        "not meaningful (evaluate a longer, less straight stretch)",
        name, result.pairs, result.ate_trans.rmse, result.alignment_rotation_uncertainty_deg);
  }

  void reportSingle(const Trajectory& gt, const eval::EvaluationResult& result,
                    const std::string& name) const {
    warnIfRpeMissing(result, name);
    warnIfRotationUndetermined(result, name);
    fmt::print("{}", eval::formatTable(result));
    if (args_.json) writeJson(*args_.json, eval::toJson(result));
    if (args_.plot) writePlot(gt, {&result}, {eval::alignedEstimateSeries(result, name)});
  }

  void reportMultiple(const Trajectory& gt, const eval::MultiRunResult& runs) const {
    for (const eval::NamedRun& run : runs.runs) {
      warnIfRpeMissing(run.result, run.name);
      warnIfRotationUndetermined(run.result, run.name);
    }
    fmt::print("{}", eval::formatTable(runs));
    if (args_.json) writeJson(*args_.json, eval::toJson(runs));
    if (args_.plot) {
      std::vector<const eval::EvaluationResult*> results;
      std::vector<eval::PlotSeries> series;
      for (const auto& run : runs.runs) {
        results.push_back(&run.result);
        series.push_back(eval::alignedEstimateSeries(run.result, run.name));
      }
      writePlot(gt, results, series);
    }
  }

  CLI::App* sub_ = nullptr;
  EvalArguments args_;
};

}  // namespace

std::unique_ptr<Command> makeEvalCommand(CLI::App& app) {
  return std::make_unique<EvalCommand>(app);
}

}  // namespace superdyna::apps
