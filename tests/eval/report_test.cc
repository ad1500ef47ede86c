#include <fmt/format.h>
#include <gtest/gtest.h>

#include <algorithm>
#include <numbers>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>

#include "eval_test_data.h"
#include "superdyna/core/error.h"
#include "superdyna/eval/plot.h"
#include "superdyna/eval/report_json.h"
#include "superdyna/eval/report_table.h"
#include "support/test_support.h"

namespace superdyna::eval {
namespace {

/// A small synthetic loop (no shared data needed): a circle of radius 5 m with a slow climb.
Trajectory circle() {
  Trajectory trajectory;
  for (int i = 0; i < 200; ++i) {
    const double a = 2.0 * std::numbers::pi * i / 200.0;
    trajectory.push_back({i * 50 * kNsPerMillisecond,
                          SE3d(expSO3(Eigen::Vector3d(0, 0, a)),
                               Eigen::Vector3d(5.0 * std::cos(a), 5.0 * std::sin(a), 0.01 * i))});
  }
  return trajectory;
}

EvaluationResult evaluateNoisyCircle(std::uint32_t seed,
                                     AlignmentMode mode = AlignmentMode::kSim3) {
  const Trajectory gt = circle();
  EvaluationOptions options;
  options.align = mode;
  return evaluate(gt, testdata::perturbed(gt, 0.02, 0.005, seed), options);
}

TEST(ReportTest, JsonHoldsTheResultValues) {
  const EvaluationResult result = evaluateNoisyCircle(1);
  const nlohmann::json j = toJson(result);
  for (const char* key :
       {"ate_rmse", "ate_mean", "ate_median", "ate_std", "ate_min", "ate_max", "ate_rot_rmse_deg",
        "scale", "pairs", "alignment", "rpe_trans", "rpe_trans_mean", "rpe_rot", "rpe_rot_mean",
        "rpe_pairs", "rpe_delta", "rpe_unit_trans", "rpe_unit_rot"}) {
    EXPECT_TRUE(j.contains(key)) << key;
  }
  EXPECT_DOUBLE_EQ(j["ate_rmse"].get<double>(), result.ate_trans.rmse);
  EXPECT_DOUBLE_EQ(j["ate_median"].get<double>(), result.ate_trans.median);
  EXPECT_DOUBLE_EQ(j["ate_std"].get<double>(), result.ate_trans.std);
  EXPECT_DOUBLE_EQ(j["ate_max"].get<double>(), result.ate_trans.max);
  EXPECT_DOUBLE_EQ(j["ate_rot_rmse_deg"].get<double>(), result.ate_rot.rmse);
  EXPECT_DOUBLE_EQ(j["scale"].get<double>(), result.scale());
  EXPECT_EQ(j["pairs"].get<std::size_t>(), result.pairs);
  EXPECT_DOUBLE_EQ(j["rpe_trans"].get<double>(), result.rpe_trans.rmse);
  EXPECT_DOUBLE_EQ(j["rpe_rot_mean"].get<double>(), result.rpe_rot.mean);
  EXPECT_EQ(j["rpe_pairs"].get<std::size_t>(), result.rpe_trans.count);
  EXPECT_DOUBLE_EQ(j["rpe_delta"].get<double>(), 1.0);
  EXPECT_EQ(j["rpe_unit_trans"], "m/m");
  EXPECT_EQ(j["rpe_unit_rot"], "deg/m");
  const nlohmann::json& alignment = j["alignment"];
  EXPECT_EQ(alignment["mode"], "sim3");
  EXPECT_DOUBLE_EQ(alignment["s"].get<double>(), result.alignment.s);
  EXPECT_DOUBLE_EQ(alignment["R"][1][2].get<double>(), result.alignment.R(1, 2));
  EXPECT_DOUBLE_EQ(alignment["t"][2].get<double>(), result.alignment.t.z());
  // Round trip through text, as scripts read it.
  EXPECT_DOUBLE_EQ(nlohmann::json::parse(j.dump())["ate_rmse"].get<double>(),
                   result.ate_trans.rmse);
}

TEST(ReportTest, MultiRunJsonSummary) {
  std::vector<NamedRun> runs;
  for (std::uint32_t seed = 1; seed <= 3; ++seed) {
    runs.push_back({"seed" + std::to_string(seed), evaluateNoisyCircle(seed)});
  }
  const MultiRunResult multi = summarizeRuns(runs);
  const nlohmann::json j = toJson(multi);
  ASSERT_EQ(j["runs"].size(), 3u);
  EXPECT_EQ(j["runs"][1]["name"], "seed2");
  EXPECT_DOUBLE_EQ(j["runs"][1]["ate_rmse"].get<double>(), runs[1].result.ate_trans.rmse);
  const nlohmann::json& summary = j["summary"];
  EXPECT_EQ(summary["runs"].get<int>(), 3);
  EXPECT_DOUBLE_EQ(summary["ate_rmse_median"].get<double>(), multi.ate_rmse.median);
  EXPECT_DOUBLE_EQ(summary["ate_rmse_mean"].get<double>(), multi.ate_rmse.mean);
  EXPECT_DOUBLE_EQ(summary["ate_rmse_std"].get<double>(), multi.ate_rmse.std);
  EXPECT_DOUBLE_EQ(summary["ate_rmse_ci95_halfwidth"].get<double>(), multi.ate_rmse.ci95_halfwidth);
  EXPECT_DOUBLE_EQ(summary["rpe_trans_median"].get<double>(), multi.rpe_trans.median);
  EXPECT_DOUBLE_EQ(summary["rpe_rot_median"].get<double>(), multi.rpe_rot.median);

  const nlohmann::json one = toJson(summarizeRuns({runs[0]}));
  EXPECT_TRUE(one["summary"]["ate_rmse_ci95_halfwidth"].is_null());
  EXPECT_TRUE(one["summary"]["ate_rmse_std"].is_null());
  EXPECT_EQ(one["summary"].dump().find("NaN"), std::string::npos);
}

TEST(ReportTest, TablesShowEveryMetric) {
  const EvaluationResult result = evaluateNoisyCircle(4);
  const std::string table = formatTable(result);
  for (const std::string& fragment : std::vector<std::string>{
           "ATE trans [m]", "ATE rot [deg]", "RPE trans [m/m]", "RPE rot [deg/m]", "rmse", "median",
           "sim3 over all pairs", fmt::format("{:.6f}", result.ate_trans.rmse)}) {
    EXPECT_NE(table.find(fragment), std::string::npos) << fragment << "\n" << table;
  }
  std::vector<NamedRun> runs = {{"first", result}, {"second", evaluateNoisyCircle(5)}};
  const std::string multi = formatTable(summarizeRuns(runs));
  for (const std::string& fragment :
       std::vector<std::string>{"first", "second", "median", "mean ± 95% CI",
                                fmt::format("{:.6f}", runs[1].result.ate_trans.rmse)}) {
    EXPECT_NE(multi.find(fragment), std::string::npos) << fragment << "\n" << multi;
  }
  EXPECT_NE(formatTable(summarizeRuns({runs[0]})).find("± n/a"), std::string::npos);
}

TEST(ReportTest, TablesShowAMissingRpeAsNotComputed) {
  EvaluationResult result = evaluateNoisyCircle(4);
  const EvaluationResult with_rpe = evaluateNoisyCircle(5);
  result.rpe_missing = "RPE: no pose pair is 1 m apart";
  const std::string table = formatTable(result);
  EXPECT_NE(table.find("RPE:        not computed (no pose pair is 1 m apart)"), std::string::npos)
      << table;
  EXPECT_NE(table.find(fmt::format("{:.6f}", result.ate_trans.rmse)), std::string::npos);
  EXPECT_NE(table.find("RPE trans [m/m]            n/a"), std::string::npos) << table;
  // Over runs, the RPE statistics are those of the runs that have one.
  const MultiRunResult runs = summarizeRuns({{"short", result}, {"long", with_rpe}});
  EXPECT_EQ(runs.rpe_trans.runs, 1u);
  EXPECT_DOUBLE_EQ(runs.rpe_trans.median, with_rpe.rpe_trans.rmse);
  EXPECT_EQ(runs.ate_rmse.runs, 2u);
  const MultiRunResult none = summarizeRuns({{"short", result}});
  EXPECT_EQ(none.rpe_trans.runs, 0u);
  const std::string multi = formatTable(none);
  EXPECT_NE(multi.find("n/a"), std::string::npos) << multi;
  EXPECT_TRUE(toJson(none)["summary"]["rpe_trans_median"].is_null());
}

TEST(ReportTest, PlotsShowTheGroundTruthOfTheEstimatesTimeSpan) {
  const Trajectory gt = circle();
  const Trajectory part(gt.begin() + 50, gt.begin() + 100);  // 2.45 s of the 9.95 s
  const EvaluationResult result = evaluate(gt, testdata::perturbed(part, 0.02, 0.005, 2), {});
  const Trajectory shown = plottedGroundTruth(gt, {&result}, PlotSpan::kEstimate);
  ASSERT_EQ(shown.size(), 50u);
  EXPECT_EQ(shown.front().t_ns, gt[50].t_ns);
  EXPECT_EQ(shown.back().t_ns, gt[99].t_ns);
  // Several estimates: from the earliest to the latest of them.
  const EvaluationResult later =
      evaluate(gt, testdata::perturbed({gt.begin() + 120, gt.begin() + 130}, 0.02, 0.005, 3), {});
  const Trajectory both = plottedGroundTruth(gt, {&result, &later}, PlotSpan::kEstimate);
  ASSERT_EQ(both.size(), 80u);
  EXPECT_EQ(both.back().t_ns, gt[129].t_ns);
  EXPECT_EQ(plottedGroundTruth(gt, {&result}, PlotSpan::kAll).size(), gt.size());
  EXPECT_EQ(parsePlotSpan("all"), PlotSpan::kAll);
  test::expectError<OptionError>([] { parsePlotSpan("half"); }, {"half"});
}

TEST(ReportTest, WritesSvgAndPngPlots) {
  test::ScratchDir dir("eval_plot");
  const Trajectory gt = circle();
  const EvaluationResult a = evaluateNoisyCircle(1), b = evaluateNoisyCircle(2);
  const std::vector<PlotSeries> estimates = {alignedEstimateSeries(a, "run <1> & co"),
                                             alignedEstimateSeries(b, "run 2")};
  PlotOptions options;
  options.width = 640;
  options.height = 480;

  writeTopViewPlot(dir / "top.svg", toPlotSeries(gt, "ground truth"), estimates, options);
  const std::string svg = test::readFile(dir / "top.svg");
  EXPECT_NE(svg.find("<svg"), std::string::npos);
  EXPECT_NE(svg.find("</svg>"), std::string::npos);
  EXPECT_NE(svg.find("run &lt;1&gt; &amp; co"), std::string::npos);  // escaped legend label
  EXPECT_NE(svg.find("x [m]"), std::string::npos);
  EXPECT_GT(std::count(svg.begin(), svg.end(), '\n'), 10);

  writeTopViewPlot(dir / "TOP.PNG", toPlotSeries(gt, "ground truth"), estimates, options);
  const cv::Mat png = cv::imread((dir / "TOP.PNG").string(), cv::IMREAD_COLOR);
  ASSERT_FALSE(png.empty());
  EXPECT_EQ(png.cols, 640);
  EXPECT_EQ(png.rows, 480);
  // Something other than white was drawn.
  cv::Mat grey;
  cv::cvtColor(png, grey, cv::COLOR_BGR2GRAY);
  EXPECT_LT(cv::countNonZero(grey == 255), 640 * 480);
}

TEST(ReportTest, TopViewShowsTheGroundPlane) {
  test::ScratchDir dir("eval_plot_plane");
  // A KITTI-like drive in the camera frame: forward along z, turning along x, y (down) flat.
  PlotSeries kitti{"gt", {}};
  for (int i = 0; i < 100; ++i) {
    kitti.positions.emplace_back(20.0 * std::sin(0.02 * i), 0.1 * std::sin(0.3 * i), 0.5 * i);
  }
  EXPECT_EQ(groundPlane(kitti), PlotPlane::kXZ);
  writeTopViewPlot(dir / "kitti.svg", kitti, {});
  const std::string svg = test::readFile(dir / "kitti.svg");
  EXPECT_NE(svg.find("Top view (x-z)"), std::string::npos);
  EXPECT_NE(svg.find("z [m]"), std::string::npos);
  EXPECT_EQ(groundPlane(toPlotSeries(circle(), "gt")), PlotPlane::kXY);  // z up
  PlotSeries wall{"gt", {{0, 0, 0}, {0, 3, 1}, {0, 6, 0}}};
  EXPECT_EQ(groundPlane(wall), PlotPlane::kYZ);
  PlotOptions forced;
  forced.plane = parsePlotPlane("xy");
  writeTopViewPlot(dir / "forced.svg", kitti, {}, forced);
  EXPECT_NE(test::readFile(dir / "forced.svg").find("Top view (x-y)"), std::string::npos);
  EXPECT_THROW(parsePlotPlane("top"), OptionError);
}

TEST(ReportTest, PlotErrors) {
  test::ScratchDir dir("eval_plot_errors");
  const PlotSeries gt = toPlotSeries(circle(), "gt");
  EXPECT_THROW(writeTopViewPlot(dir / "top.jpg", gt, {}), OptionError);
  EXPECT_THROW(writeTopViewPlot(dir / "top", gt, {}), OptionError);
  PlotOptions tiny;
  tiny.width = 10;
  EXPECT_THROW(writeTopViewPlot(dir / "top.svg", gt, {}, tiny), OptionError);
  EXPECT_THROW(writeTopViewPlot(dir / "top.svg", PlotSeries{"empty", {}}, {}), InputError);
  EXPECT_THROW(writeTopViewPlot(dir / "missing" / "top.svg", gt, {}), InputError);
  EXPECT_THROW(writeTopViewPlot(dir / "missing" / "top.png", gt, {}), InputError);
}

}  // namespace
}  // namespace superdyna::eval
