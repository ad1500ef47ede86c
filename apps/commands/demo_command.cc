#include "commands/demo_command.h"

#include <fmt/format.h>
#include <spdlog/spdlog.h>

#include <filesystem>
#include <optional>

#include "commands/output_files.h"
#include "superdyna/eval/evaluate.h"
#include "superdyna/eval/plot.h"
#include "superdyna/eval/report_json.h"
#include "superdyna/eval/report_table.h"
#include "superdyna/io/trajectory_io.h"
#include "superdyna/sim/procedural_trajectory.h"

namespace superdyna::apps {

namespace fs = std::filesystem;

namespace {

class DemoCommand : public Command {
 public:
  explicit DemoCommand(CLI::App& app) {
    sub_ = app.add_subcommand(
        "demo",
        "Evaluation demo without SLAM: generate a flight, simulate a drifting estimate of it in an "
        "unknown frame and scale, and evaluate it (ATE after SE(3) and Sim(3) alignment, RPE)");
    sub_->add_option("--out", out_, "Output folder (trajectories, JSON reports, plot)")
        ->capture_default_str();
    sub_->add_option("--gt", gt_file_,
                     "Use this real trajectory as the ground truth instead of a generated flight")
        ->check(CLI::ExistingFile);
    sub_->add_option("--duration", duration_s_, "Length of the generated flight [s]")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub_->add_option("--scale", scale_, "Scale error of the simulated estimate (1 = metric)")
        ->check(CLI::PositiveNumber)
        ->capture_default_str();
    sub_->add_option("--seed", seed_, "Seed of the simulated estimate's errors")
        ->capture_default_str();
  }

  CLI::App* subcommand() const override { return sub_; }

  int run() override {
    fs::create_directories(out_);
    const Trajectory gt = groundTruth();
    const Trajectory estimate = sim::simulateEstimate(gt, estimateErrors());
    const fs::path gt_file = out_ / "groundtruth.txt";
    const fs::path est_file = out_ / "estimate.txt";
    io::writeTrajectory(gt_file, gt, io::TrajectoryFormat::kTum);
    io::writeTrajectory(est_file, estimate, io::TrajectoryFormat::kTum);
    spdlog::info("ground truth: {} poses over {:.1f} s, {:.1f} m of path", gt.size(),
                 nsToSeconds(gt.back().t_ns - gt.front().t_ns), pathLength(gt));

    for (const auto mode : {eval::AlignmentMode::kSE3, eval::AlignmentMode::kSim3}) {
      eval::EvaluationOptions options;
      options.align = mode;
      const eval::EvaluationResult result = eval::evaluate(gt, estimate, options);
      fmt::print("\n== alignment {} ==\n{}", eval::toString(mode), eval::formatTable(result));
      writeJson(out_ / fmt::format("eval_{}.json", eval::toString(mode)), eval::toJson(result));
      if (mode == eval::AlignmentMode::kSim3) {
        eval::writeTopViewPlot(out_ / "topview.svg", eval::toPlotSeries(gt, "ground truth"),
                               {eval::alignedEstimateSeries(result, "estimate (Sim(3)-aligned)")});
      }
    }
    fmt::print(
        "\nOutputs in {}/. The same evaluation by hand:\n  superdyna eval --gt {} --est {} "
        "--align sim3 --json report.json --plot topview.svg\n",
        out_.string(), gt_file.string(), est_file.string());
    return 0;
  }

 private:
  Trajectory groundTruth() const {
    if (gt_file_) return io::readTrajectory(*gt_file_);
    sim::LissajousOptions flight;
    flight.duration_s = duration_s_;
    return sim::makeLissajousTrajectory(flight);
  }

  sim::EstimateErrorOptions estimateErrors() const {
    sim::EstimateErrorOptions errors;
    errors.seed = seed_;
    errors.scale = scale_;
    // The estimator's world frame: rotated about gravity and shifted, as a SLAM map would be.
    errors.world_offset.R = expSO3(Eigen::Vector3d(0.0, 0.0, 1.1));
    errors.world_offset.t = Eigen::Vector3d(2.0, -3.0, 0.5);
    return errors;
  }

  CLI::App* sub_ = nullptr;
  fs::path out_ = "superdyna_demo";
  std::optional<fs::path> gt_file_;
  double duration_s_ = 60.0;
  double scale_ = 1.0;
  std::uint64_t seed_ = 1;
};

}  // namespace

std::unique_ptr<Command> makeDemoCommand(CLI::App& app) {
  return std::make_unique<DemoCommand>(app);
}

}  // namespace superdyna::apps
