#include "superdyna/sweep/sweep.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <map>
#include <string>

#include "superdyna/sweep/charts.h"
#include "superdyna/sweep/dispatch.h"
#include "superdyna/sweep/process.h"
#include "superdyna/sweep/report_html.h"
#include "superdyna/sweep/spec.h"
#include "superdyna/sweep/tables.h"
#include "support/test_support.h"

namespace superdyna::sweep {
namespace {

namespace fs = std::filesystem;

/// A recorded "dataset": a 10 s EuRoC ground truth of a 4 m circle at 20 Hz.
fs::path writeCircleDataset(const fs::path& dir) {
  const fs::path gt = dir / "mav0/state_groundtruth_estimate0/data.csv";
  fs::create_directories(gt.parent_path());
  std::string text = "#timestamp,p_x,p_y,p_z,q_w,q_x,q_y,q_z\n";
  for (int i = 0; i < 200; ++i) {
    const double a = 2.0 * M_PI * i / 200.0;
    text += fmt::format("{},{:.6f},{:.6f},1.0,{:.9f},0,0,{:.9f}\n", 1000000000LL + i * 50000000LL,
                        2.0 * std::cos(a), 2.0 * std::sin(a), std::cos(a / 2), std::sin(a / 2));
  }
  test::writeFile(gt, text);
  return dir;
}

/// A spec with a recorded sequence and two external "systems": one returns the ground truth
/// (EuRoC CSV), one the ground truth shifted by 3 cm in x as TUM with nanosecond times.
std::string peerSpec(const fs::path& dataset) {
  return fmt::format(R"(name: peers
runs: 2
sequences:
  - name: circle
    dataset: euroc
    path: {0}
configs:
  - name: exact
    command: "cp {{gt}} {{out}}/estimate.csv"
    trajectory: "{{out}}/estimate.csv"
    trajectory_format: euroc
  - name: shifted
    command: >-
      awk -F, 'NR > 1 {{ printf "%s.000000 %.6f %s %s %s %s %s %s\n", $1, $2 + 0.03, $3, $4,
      $6, $7, $8, $5 }}' {{gt}} > {{out}}/estimate.txt
    trajectory: "{{out}}/estimate.txt"
    trajectory_format: tum
    time_unit: ns
    align: none
tables:
  - {{name: transposed, metric: ate_runs, rows: configs}}
)",
                     dataset.string());
}

/// The peer spec on a circle dataset in `dir`, planned into dir/out.
struct PeerSweep {
  explicit PeerSweep(const fs::path& dir)
      : spec(writeAndLoad(dir)), plan(planSweep(spec, dir / "out", "/bin/false")) {}
  static SweepSpec writeAndLoad(const fs::path& dir) {
    test::writeFile(dir / "spec.yaml", peerSpec(writeCircleDataset(dir / "dataset")));
    return loadSweepSpec(dir / "spec.yaml");
  }
  SweepSpec spec;
  SweepPlan plan;
};

TEST(SweepSpec, ReadsSequencesConfigsTablesAndExpandsTheEnvironment) {
  test::ScratchDir dir("sweep_spec");
  test::writeFile(dir / "base.yaml", "tracker: {}\n");
  test::writeFile(dir / "spec.yaml", R"(name: demo
runs: 3
eval: {max_diff: 0.02, rpe_delta: 2.0}
sequences:
  - name: sim
    simulate: [--scene, indoor, --duration, 3, --seed, "${SWEEP_TEST_SEED:-7}"]
  - name: other
    simulate: [--scene, street]
configs:
  - name: orb
    mode: stereo-inertial
    config: base.yaml
    set: {dynamic.mode: semantic}
    args: [--loop-closing, "off"]
  - name: mono
    mode: mono
    sequences: [other]
    deterministic: false
  - name: once
    mode: stereo
    runs: 1
tables:
  - {name: t10, metric: ate_mean_ci, rows: configs, configs: [mono, orb]}
)");
  const test::ScopedEnv seed("SWEEP_TEST_SEED", "11");
  const SweepSpec spec = loadSweepSpec(dir / "spec.yaml");
  EXPECT_EQ(spec.name, "demo");
  EXPECT_EQ(spec.runs, 3);
  EXPECT_DOUBLE_EQ(spec.eval.max_diff_s, 0.02);
  ASSERT_EQ(spec.sequences.size(), 2u);
  EXPECT_EQ(spec.sequences[0].simulate_args.back(), "11");
  EXPECT_EQ(spec.config("orb").config, fs::weakly_canonical(dir / "base.yaml"));
  EXPECT_EQ(spec.config("orb").set.at("dynamic.mode"), "semantic");
  EXPECT_EQ(spec.config("orb").alignment(), "se3");
  EXPECT_EQ(spec.config("mono").alignment(), "sim3");
  EXPECT_FALSE(spec.config("mono").runsOn("sim"));
  EXPECT_TRUE(spec.tables[0].rows_are_configs);

  const SweepPlan plan = planSweep(spec, dir / "out", "/usr/bin/superdyna");
  // orb on both sequences, mono on one, `once` on both with its own single run
  EXPECT_EQ(plan.cells.size(), 3u * 2u + 3u + 2u);
  EXPECT_EQ(spec.config("once").runs, 1);
  EXPECT_EQ(plan.cells.front().dir, fs::absolute(dir / "out/cells/sim/orb/run-1"));
  EXPECT_EQ(plan.sequences[0].simulate.back(), fs::absolute(dir / "out/sequences/sim").string());
  const std::vector<std::string> command = cellCommand(spec, plan, plan.cells.front());
  const std::string line = shellQuote(command);
  for (const std::string& part : std::vector<std::string>{
           "/usr/bin/superdyna run --dataset euroc --path", "--mode stereo-inertial",
           "--config " + (plan.cells.front().dir / "config.yaml").string(), "--deterministic",
           "--loop-closing off", "--stats"}) {
    EXPECT_NE(line.find(part), std::string::npos) << part << " not in " << line;
  }
}

TEST(SweepSpec, ErrorsNameTheFileTheLineAndTheField) {
  test::ScratchDir dir("sweep_spec_errors");
  const auto expectSpecError = [&](const std::string& text,
                                   std::initializer_list<std::string> fragments) {
    test::writeFile(dir / "bad.yaml", text);
    test::expectError([&] { loadSweepSpec(dir / "bad.yaml"); }, fragments);
  };
  const std::string sequence = "sequences: [{name: a, simulate: [--seed, 1]}]\n";
  expectSpecError(sequence + "configs: [{name: x, mode: stereo-intertial}]\n",
                  {"bad.yaml:2", "configs[0].mode", "stereo-intertial"});
  expectSpecError(sequence + "configs: [{name: x, config: missing.yaml}]\n",
                  {"configs[0].config", "missing.yaml", "does not exist"});
  expectSpecError(sequence + "configs: [{name: x, colour: red}]\n",
                  {"configs[0].colour", "unknown field"});
  expectSpecError(sequence + "configs: [{name: x}, {name: x}]\n", {"two configs are named 'x'"});
  expectSpecError(sequence + "configs: [{name: x, sequences: [b]}]\n", {"unknown sequence 'b'"});
  expectSpecError(sequence + "configs: [{name: x}]\ntables: [{name: t, metric: speed}]\n",
                  {"tables[0].metric", "'speed' is not one of"});
  expectSpecError(sequence + "configs: [{name: ../x}]\n", {"'../x' is not a usable name"});
  expectSpecError(sequence + "configs: [{name: x}]\nruns: 0\n", {"runs", "whole number"});
  expectSpecError(
      "sequences: [{name: a, simulate: [--seed, \"${SWEEP_TEST_UNSET_VARIABLE}\"]}]\n"
      "configs: [{name: x}]\n",
      {"SWEEP_TEST_UNSET_VARIABLE is not set", "sequences[0].simulate[1]"});
  expectSpecError("configs: [{name: x}]\n", {"sequences", "missing field"});
}

TEST(SweepSpec, TheBenchSpecsLoadAndPlanTheirCells) {
  SUPERDYNA_REQUIRE_SHARED(euroc, "data/euroc/V1_01_easy_micro");
  const test::ScopedEnv shared("SUPERDYNA_SHARED_DIR", test::sharedDir().string());
  std::map<std::string, std::size_t> cells;
  for (const auto& entry : fs::directory_iterator(fs::path(SUPERDYNA_SOURCE_DIR) / "bench")) {
    if (!entry.path().string().ends_with(".sweep.yaml")) continue;
    const SweepSpec spec = loadSweepSpec(entry.path());
    cells[spec.name] = planSweep(spec, "/tmp/unused", "superdyna").cells.size();
  }
  // The backbone table (docs/results/backbone.md): 17 cells; the ablation: 2 sequences x 7
  // configs x 5 runs.
  EXPECT_EQ(cells["backbone"], 17u);
  EXPECT_EQ(cells["dynamic-ablation"], 70u);
  EXPECT_EQ(cells["pipeline-speed"], 4u);
  // Issue 50's table: si-sg on 6 dynamic sequences and their 6 static worlds, si-off and
  // si-semantic on the 6, ORB-SLAM3 stereo-inertial 3 runs on the 6, mono-inertial on the 3
  // robot sequences (ours once, ORB-SLAM3 three times).
  EXPECT_EQ(cells["dynamic-peers"], 12u + 6u + 6u + 18u + 3u + 9u);
}

TEST(SweepSpec, ExpandsVariablesWithDefaults) {
  const test::ScopedEnv set("SWEEP_TEST_DIR", "/data");
  EXPECT_EQ(expandEnvironment("${SWEEP_TEST_DIR}/x ${SWEEP_TEST_NONE:-../shared}", "f"),
            "/data/x ../shared");
  EXPECT_EQ(expandEnvironment("plain {out}", "f"), "plain {out}");
  test::expectError([] { expandEnvironment("${SWEEP_TEST_DIR", "f"); }, {"closing"});
}

CellResult run(const std::string& config, int k, double ate_m, bool ok = true) {
  CellResult r;
  r.sequence = "seq";
  r.config = config;
  r.run = k;
  r.ok = ok;
  r.ate_rmse_m = ok ? ate_m : kNotMeasured;
  r.rpe_trans = 0.001 * k;
  r.rpe_rot = 0.01;
  r.lost_frames = k - 1;
  r.fps = 20.0 + k;
  r.frames = 100;
  r.cpu_s = 5.0;
  r.peak_rss_mb = 300 + k;
  r.stage_ms = {{"extract", 10.0 + k}, {"track", 4.0}};
  if (!ok) r.error = "exit status 1";
  return r;
}

SweepSpec twoConfigSpec() {
  SweepSpec spec;
  spec.name = "t";
  spec.runs = 3;
  spec.sequences = {SequenceSpec{}};
  spec.sequences[0].name = "seq";
  spec.configs = {ConfigSpec{}, ConfigSpec{}};
  spec.configs[0].name = "a";
  spec.configs[1].name = "b";
  return spec;
}

TEST(SweepTables, MedianMeanConfidenceIntervalAndFailedRuns) {
  const SweepSpec spec = twoConfigSpec();
  const std::vector<CellResult> results = {run("a", 2, 0.012), run("a", 1, 0.010),
                                           run("a", 3, 0.014), run("b", 1, 1.5),
                                           run("b", 2, 0.0, false)};
  const std::vector<CellGroup> groups = groupResults(spec, results);
  ASSERT_EQ(groups.size(), 2u);
  EXPECT_EQ(groups[0].runs[0].run, 1);  // sorted by run
  // Three runs 1.0 / 1.2 / 1.4 cm: std 0.2 cm, t(0.975, 2) = 4.303, half-width 0.50 cm.
  EXPECT_EQ(metric("ate_median").text(groups[0]), "1.20 cm");
  EXPECT_EQ(metric("ate_mean_ci").text(groups[0]), "1.20 ± 0.50 cm");
  EXPECT_EQ(metric("ate_runs").text(groups[0]), "1.00 cm / 1.20 cm / 1.40 cm");
  EXPECT_EQ(metric("ate_median").text(groups[1]), "1.500 m (1 of 2 failed)");
  EXPECT_EQ(metric("ate_runs").text(groups[1]), "1.500 m / failed");
  EXPECT_EQ(metric("lost_frames").text(groups[0]), "1");
  EXPECT_EQ(metric("peak_rss_mb").text(groups[0]), "303");
  EXPECT_DOUBLE_EQ(metric("cpu_ms_per_frame").value(groups[0]), 50.0);

  const TableText accuracy = accuracyTable(groups);
  EXPECT_NE(
      accuracy.markdown.find("| seq | a | 3 / 3 | 1.20 cm | 1.20 ± 0.50 cm | 1.00 cm | 1.40 cm |"),
      std::string::npos)
      << accuracy.markdown;
  EXPECT_NE(accuracy.csv.find("seq,a,3 / 3,0.012,0.012,0.01,0.014,"), std::string::npos)
      << accuracy.csv;
  const TableText timing = timingTable(spec, groups);
  EXPECT_NE(timing.markdown.find("| a | 3 | 12.00 | 4.00 |"), std::string::npos) << timing.markdown;

  TableSpec transposed{"t10", "Ablation", "ate_median", true, {"b", "a"}, {}};
  const TableText matrix = matrixTable(spec, transposed, groups);
  EXPECT_NE(
      matrix.markdown.find("| config | seq |\n| --- | --- |\n| b | 1.500 m (1 of 2 failed) |\n"
                           "| a | 1.20 cm |\n"),
      std::string::npos)
      << matrix.markdown;
  EXPECT_EQ(formatMetres(0.00784), "0.78 cm");
  EXPECT_EQ(formatMetres(2.5), "2.500 m");
}

TEST(SweepTables, MarkdownBecomesAnHtmlTable) {
  EXPECT_EQ(markdownTableToHtml("| a | b <c> |\n| --- | --- |\n| 1 | 2 |\n"),
            "<table>\n<tr><th>a</th><th>b &lt;c&gt;</th></tr>\n<tr><td>1</td><td>2</td></tr>\n"
            "</table>\n");
}

TEST(SweepProcess, ReportsExitStatusSignalCpuTimeAndLog) {
  test::ScratchDir dir("sweep_process");
  const ProcessResult ok =
      runProcess({"sh", "-c", "echo hello; echo oops >&2; exit 3"}, dir / "log.txt", dir.path());
  EXPECT_EQ(ok.exit_code, 3);
  EXPECT_EQ(ok.describe(), "exit status 3");
  EXPECT_EQ(test::readFile(dir / "log.txt"), "hello\noops\n");
  const ProcessResult killed = runProcess({"sh", "-c", "kill -9 $$"}, dir / "log2.txt", dir.path());
  EXPECT_EQ(killed.signal, 9);
  EXPECT_FALSE(killed.ok());
  // A child's CPU time is counted (a busy loop of a few hundred ms).
  const ProcessResult busy =
      runProcess({"sh", "-c", "i=0; while [ $i -lt 200000 ]; do i=$((i+1)); done"},
                 dir / "log3.txt", dir.path());
  EXPECT_GT(busy.cpu_s, 0.0);
  EXPECT_GT(busy.peak_rss_mb, 0.0);
  const ProcessResult missing = runProcess({"no-such-program-here"}, dir / "log4.txt", dir.path());
  EXPECT_EQ(missing.exit_code, 127);
  EXPECT_EQ(shellQuote({"run", "--path", "a b", "it's"}), "run --path 'a b' 'it'\\''s'");
  EXPECT_EQ(fingerprint(""), "cbf29ce484222325");  // FNV-1a's offset basis
}

TEST(SweepCells, ExternalSystemsAreScoredResumedAndRerunWhenTheirDefinitionChanges) {
  test::ScratchDir dir("sweep_cells");
  const PeerSweep peers(dir.path());
  const SweepSpec& spec = peers.spec;
  const SweepPlan& plan = peers.plan;
  ASSERT_EQ(plan.cells.size(), 4u);
  for (const CellTask& cell : plan.cells) {
    EXPECT_TRUE(cellNeeded(spec, plan, cell, false));
    const CellResult r = runCell(spec, plan, cell, "test");
    ASSERT_TRUE(r.ok) << cell.id() << ": " << r.error;
    EXPECT_FALSE(cellNeeded(spec, plan, cell, false));
    for (const char* file :
         {"command.txt", "cell.json", "log.txt", "eval.json", "pose_errors.csv"}) {
      EXPECT_TRUE(fs::exists(cell.dir / file)) << cell.id() << " " << file;
    }
  }
  const std::vector<CellResult> results = collectResults(spec, plan);
  ASSERT_EQ(results.size(), 4u);
  EXPECT_LT(results[0].ate_rmse_m, 1e-6);          // the exact copy
  EXPECT_NEAR(results[2].ate_rmse_m, 0.03, 1e-6);  // 3 cm, no alignment
  EXPECT_TRUE(std::isnan(results[2].fps));         // external: no run statistics
  EXPECT_GT(results[2].peak_rss_mb, 0.0);          // but the process was measured
  const std::vector<TableText> tables = allTables(spec, groupResults(spec, results));
  EXPECT_NE(tables[0].markdown.find("| circle | 0.00 cm | 3.00 cm |"), std::string::npos)
      << tables[0].markdown;

  // A failing command is a failed cell with the log's end, not an exception.
  std::string text = test::readFile(dir / "spec.yaml");
  text.replace(text.find("cp {gt}"), 7, "cp /nonexistent-gt");
  test::writeFile(dir / "spec.yaml", text);
  const SweepSpec changed = loadSweepSpec(dir / "spec.yaml");
  EXPECT_TRUE(cellNeeded(changed, plan, plan.cells[0], false));   // another definition
  EXPECT_FALSE(cellNeeded(changed, plan, plan.cells[2], false));  // untouched config
  const CellResult failed = runCell(changed, plan, plan.cells[0], "test");
  EXPECT_FALSE(failed.ok);
  EXPECT_NE(failed.error.find("exit status 1"), std::string::npos) << failed.error;
  EXPECT_NE(failed.error.find("nonexistent-gt"), std::string::npos) << failed.error;
  EXPECT_FALSE(cellNeeded(changed, plan, plan.cells[0], false));
  EXPECT_TRUE(cellNeeded(changed, plan, plan.cells[0], true));  // --rerun-failed
  // A result of another definition is not part of a sweep: the changed sweep has the failed
  // run 1 of "exact" (its run 2 is stale) and both runs of "shifted".
  const std::vector<CellResult> now = collectResults(changed, plan);
  ASSERT_EQ(now.size(), 3u);
  EXPECT_FALSE(now[0].ok);
  EXPECT_EQ(now[1].config, "shifted");
  EXPECT_EQ(collectResults(spec, plan).size(), 3u);  // run 2 of "exact" and "shifted"
}

TEST(SweepDispatch, TheSlurmScriptRunsTheTaskOfItsArrayIndex) {
  DispatchOptions options;
  options.kind = parseDispatchKind("slurm");
  options.superdyna = "/opt/superdyna";
  options.spec = "/data/my spec.yaml";
  options.out = "/scratch/sweep";
  options.rerun_failed = true;
  const std::string script = slurmScript(options, "/scratch/sweep/dispatch/cells.tasks", "cells");
  for (const std::string& part : std::vector<std::string>{
           "#!/bin/bash", "#SBATCH --output=/scratch/sweep/dispatch/cells-%a.log",
           "sed -n \"$((SLURM_ARRAY_TASK_ID + 1))p\" /scratch/sweep/dispatch/cells.tasks",
           "exec /opt/superdyna sweep '/data/my spec.yaml' --out /scratch/sweep --rerun-failed "
           "--task \"$task\""}) {
    EXPECT_NE(script.find(part), std::string::npos) << part << "\n" << script;
  }
  test::expectError<OptionError>([] { parseDispatchKind("mpi"); }, {"--dispatch", "mpi"});
}

TEST(SweepReport, PageHasEveryTablePlotAndTheStatusScript) {
  test::ScratchDir dir("sweep_report");
  const PeerSweep peers(dir.path());
  const SweepSpec& spec = peers.spec;
  const SweepPlan& plan = peers.plan;
  for (const CellTask& cell : plan.cells)
    runCell(spec, plan, cell, "test");
  const auto groups = groupResults(spec, collectResults(spec, plan));
  const auto tables = allTables(spec, groups);
  const fs::path page = writeHtmlReport({spec, plan, groups, tables, "abc123"}, dir / "report");
  const std::string html = test::readFile(page);
  for (const std::string& part : std::vector<std::string>{
           "<h1>Sweep peers</h1>", "plots/circle_top.svg", "plots/circle_ate.svg",
           "<th>config</th>", "abc123", "document.body.dataset.status"}) {
    EXPECT_NE(html.find(part), std::string::npos) << part;
  }
  const std::string top = test::readFile(dir / "report/plots/circle_top.svg");
  EXPECT_NE(top.find("x [m]"), std::string::npos);  // the circle lies in x-y
  EXPECT_NE(top.find("shifted"), std::string::npos);
  EXPECT_NE(test::readFile(dir / "report/plots/circle_ate.svg").find("<polyline"),
            std::string::npos);
}

}  // namespace
}  // namespace superdyna::sweep
