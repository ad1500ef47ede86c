#include "superdyna/sweep/sweep.h"

#include <fmt/format.h>
#include <unistd.h>
#include <yaml-cpp/yaml.h>

#include <cstdint>
#include <ctime>
#include <fstream>
#include <nlohmann/json.hpp>
#include <sstream>
#include <thread>

#include "superdyna/core/atomic_file.h"
#include "superdyna/core/error.h"
#include "superdyna/eval/dynamic_decisions.h"
#include "superdyna/eval/evaluate.h"
#include "superdyna/eval/report_json.h"
#include "superdyna/io/trajectory_io.h"
#include "superdyna/sweep/process.h"
#include "superdyna/sweep/sweep_build_info.h"

namespace superdyna::sweep {

namespace fs = std::filesystem;

namespace {

constexpr const char* kResultFile = "result.json";
const fs::path kEurocGroundTruth = "mav0/state_groundtruth_estimate0/data.csv";
const fs::path kInstanceStates = "mav0/instance_states.csv";
constexpr int kDecisionMinPairs = 8;  // superdyna eval-dynamic's default

/// Whether the cell's keypoints carry instance labels, so that it decides about moving objects.
bool labelsKeypoints(const SequenceSpec& s, const ConfigSpec& c) {
  for (const auto* args : {&s.run_args, &c.args}) {
    for (const std::string& a : *args) {
      if (a == "--instance-masks" || a == "--segmenter" || a.rfind("--segmenter=", 0) == 0) {
        return true;
      }
    }
  }
  return false;
}

void writeText(const fs::path& file, const std::string& text) {
  AtomicFile out(file);
  out.stream() << text;
  out.commit();
}

std::string readText(const fs::path& file) {
  std::ifstream in(file, std::ios::binary);
  std::ostringstream text;
  text << in.rdbuf();
  return text.str();
}

std::string utcNow() {
  const std::time_t now = std::time(nullptr);
  std::tm utc{};
  gmtime_r(&now, &utc);
  char text[32];
  std::strftime(text, sizeof(text), "%Y-%m-%dT%H:%M:%SZ", &utc);
  return text;
}

nlohmann::json machine() {
  char host[256] = {};
  gethostname(host, sizeof(host) - 1);
  std::string cpu = "unknown";
  std::ifstream cpuinfo("/proc/cpuinfo");
  for (std::string line; std::getline(cpuinfo, line);) {
    if (line.rfind("model name", 0) == 0 && line.find(':') != std::string::npos) {
      cpu = line.substr(line.find(':') + 2);
      break;
    }
  }
  return {{"host", host}, {"cpu", cpu}, {"cores", std::thread::hardware_concurrency()}};
}

/// Replaces every {key} of `values` in `text`.
std::string fillTemplate(std::string text,
                         const std::vector<std::pair<std::string, std::string>>& values) {
  for (const auto& [key, value] : values) {
    const std::string token = "{" + key + "}";
    for (std::size_t at = text.find(token); at != std::string::npos;
         at = text.find(token, at + value.size())) {
      text.replace(at, token.size(), value);
    }
  }
  return text;
}

std::vector<std::pair<std::string, std::string>> placeholders(const SequenceSpec& s,
                                                              const SequenceTask& task,
                                                              const ConfigSpec& c,
                                                              const CellTask& cell) {
  return {{"path", task.dataset.string()},
          {"dataset", s.dataset},
          {"mode", c.mode},
          {"sequence", s.name},
          {"run", std::to_string(cell.run)},
          {"out", cell.dir.string()},
          {"gt", task.ground_truth.string()}};
}

/// Sets the dotted key ("dynamic.mode") in `root`, creating the maps on the way.
void setDotted(YAML::Node root, const std::string& key, const std::string& value) {
  const std::size_t dot = key.find('.');
  if (dot == std::string::npos) {
    root[key] = value;
    return;
  }
  const std::string head = key.substr(0, dot);
  if (!root[head] || !root[head].IsMap()) root[head] = YAML::Node(YAML::NodeType::Map);
  setDotted(root[head], key.substr(dot + 1), value);
}

/// The config file a cell runs with: the spec's, or a copy with the cell's `set` applied.
std::string cellConfigText(const ConfigSpec& c) {
  if (c.set.empty()) return c.config.empty() ? std::string() : readText(c.config);
  YAML::Node root = c.config.empty() ? YAML::Node(YAML::NodeType::Map) : YAML::LoadFile(c.config);
  for (const auto& [key, value] : c.set)
    setDotted(root, key, value);
  YAML::Emitter out;
  out << root;
  return std::string("# ") + (c.config.empty() ? "defaults" : c.config.string()) +
         " with the sweep config's `set`\n" + out.c_str() + "\n";
}

fs::path cellConfigPath(const ConfigSpec& c, const CellTask& cell) {
  return c.set.empty() ? c.config : cell.dir / "config.yaml";
}

fs::path estimatePath(const SweepSpec& spec, const SweepPlan& plan, const CellTask& cell) {
  const ConfigSpec& c = spec.config(cell.config);
  if (!c.external()) return cell.dir / "trajectory.txt";
  return fillTemplate(c.trajectory, placeholders(spec.sequence(cell.sequence),
                                                 plan.sequence(cell.sequence), c, cell));
}

eval::EvaluationOptions evaluationOptions(const SweepSpec& spec, const ConfigSpec& c) {
  eval::EvaluationOptions options;
  options.align = eval::parseAlignmentMode(c.alignment());
  options.association.max_diff_ns = static_cast<TimeNs>(spec.eval.max_diff_s * 1e9);
  options.rpe.delta = spec.eval.rpe_delta;
  options.rpe.unit = eval::parseDeltaUnit(spec.eval.rpe_unit);
  options.require_rpe = false;  // a path shorter than the delta still has an ATE
  return options;
}

void writePoseErrors(const fs::path& file, const eval::EvaluationResult& result) {
  AtomicFile out(file);
  out.stream() << "t_s,gt_x,gt_y,gt_z,est_x,est_y,est_z,trans_error_m,rot_error_deg\n";
  for (const eval::PoseError& p : result.poses) {
    out.stream() << fmt::format("{:.9f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.6f},{:.4f}\n",
                                nsToSeconds(p.t_ns), p.gt_position.x(), p.gt_position.y(),
                                p.gt_position.z(), p.aligned_position.x(), p.aligned_position.y(),
                                p.aligned_position.z(), p.trans_error_m, p.rot_error_deg);
  }
  out.commit();
}

/// Scores the cell's estimate; fills the accuracy fields of `result`.
void scoreCell(const SweepSpec& spec, const SweepPlan& plan, const CellTask& cell,
               CellResult& result) {
  const ConfigSpec& c = spec.config(cell.config);
  const SequenceTask& task = plan.sequence(cell.sequence);
  io::TrajectoryReadOptions gt_options;
  gt_options.format = io::parseTrajectoryFormat(spec.sequence(cell.sequence).ground_truth_format);
  if (!task.ground_truth_times.empty()) gt_options.kitti_times = task.ground_truth_times;
  io::TrajectoryReadOptions est_options;
  est_options.format = io::parseTrajectoryFormat(c.external() ? c.trajectory_format : "tum");
  est_options.tum_time_in_ns = c.time_unit == "ns";
  const Trajectory gt = io::readTrajectory(task.ground_truth, gt_options);
  const Trajectory est = io::readTrajectory(estimatePath(spec, plan, cell), est_options);
  const eval::EvaluationResult e = eval::evaluate(gt, est, evaluationOptions(spec, c));
  writeText(cell.dir / "eval.json", eval::toJson(e).dump(2) + "\n");
  writePoseErrors(cell.dir / "pose_errors.csv", e);
  result.ate_rmse_m = e.ate_trans.rmse;
  result.ate_rot_deg = e.ate_rot.rmse;
  result.rpe_trans = e.rpe_missing.empty() ? e.rpe_trans.rmse : kNotMeasured;
  result.rpe_rot = e.rpe_missing.empty() ? e.rpe_rot.rmse : kNotMeasured;
  result.rpe_trans_unit = eval::rpeTransUnit(e.rpe_options.unit);
  result.rpe_rot_unit = e.rpe_options.unit == eval::DeltaUnit::kMeters ? "deg/m" : "deg";
}

/// The moving-object decisions of the run against the simulator's truth, when both exist.
void scoreDecisions(const CellTask& cell, const SequenceTask& task, CellResult& result) {
  const fs::path log = cell.dir / "decisions.csv";
  const fs::path truth = task.dataset / kInstanceStates;
  if (!fs::exists(log) || !fs::exists(truth)) return;
  const eval::DecisionScore score = eval::scoreDecisions(
      eval::readDynamicLog(log), eval::readInstanceStates(truth), kDecisionMinPairs);
  result.moving_precision = score.all.precision();
  result.moving_recall = score.all.recall();
  result.static_kept = score.all.staticKeptShare();
}

/// The numbers `superdyna run --stats` wrote, when it did.
void readRunStats(const fs::path& file, CellResult& result) {
  if (!fs::exists(file)) return;
  std::ifstream in(file);
  const nlohmann::json stats = nlohmann::json::parse(in, nullptr, /*allow_exceptions=*/false);
  if (!stats.is_object()) throw InputError(InputLocation(file), "not a JSON object");
  const auto get = [&](const char* key) {
    return stats.contains(key) && stats[key].is_number() ? stats[key].get<double>() : kNotMeasured;
  };
  result.frames = get("frames");
  result.lost_frames = get("lost_frames");
  result.map_resets = get("map_resets");
  result.fps = get("fps");
  if (stats.contains("mean_ms_per_frame") && stats["mean_ms_per_frame"].is_object()) {
    for (const auto& [stage, ms] : stats["mean_ms_per_frame"].items()) {
      if (ms.is_number() && ms.get<double>() > 0.0) result.stage_ms[stage] = ms.get<double>();
    }
  }
}

void writeCellRecord(const CellTask& cell, const std::vector<std::string>& command,
                     const std::string& hash, const std::string& revision) {
  writeText(cell.dir / "command.txt", shellQuote(command) + "\n");
  const nlohmann::json record = {{"cell", cell.id()},    {"command", command},
                                 {"cell_hash", hash},    {"git_revision", revision},
                                 {"machine", machine()}, {"started", utcNow()}};
  writeText(cell.dir / "cell.json", record.dump(2) + "\n");
}

}  // namespace

std::string CellTask::id() const {
  return fmt::format("{}/{}/run-{}", sequence, config, run);
}

const SequenceTask& SweepPlan::sequence(const std::string& name) const {
  for (const SequenceTask& s : sequences) {
    if (s.name == name) return s;
  }
  throw InputError(fmt::format("the sweep has no sequence '{}'", name));
}

std::string fingerprint(const std::string& text) {
  std::uint64_t hash = 14695981039346656037ull;
  for (unsigned char ch : text) {
    hash ^= ch;
    hash *= 1099511628211ull;
  }
  return fmt::format("{:016x}", hash);
}

std::string buildRevision() {
  return kBuildRevision;
}

SweepPlan planSweep(const SweepSpec& spec, const fs::path& out, const fs::path& superdyna) {
  SweepPlan plan;
  plan.out = fs::absolute(out);
  plan.spec_dir = spec.file.parent_path();
  plan.superdyna = superdyna;
  for (const SequenceSpec& s : spec.sequences) {
    SequenceTask task;
    task.name = s.name;
    if (s.simulated()) {
      task.dataset = plan.out / "sequences" / s.name;
      task.simulate = {superdyna.string(), "simulate"};
      task.simulate.insert(task.simulate.end(), s.simulate_args.begin(), s.simulate_args.end());
      task.simulate.insert(task.simulate.end(), {"--out", task.dataset.string()});
      task.marker = plan.out / "sequences" / (s.name + ".json");
      task.hash = fingerprint(shellQuote(task.simulate));
    } else {
      task.dataset = s.path;
    }
    task.ground_truth =
        task.dataset / (s.ground_truth.empty() ? kEurocGroundTruth : s.ground_truth);
    if (!s.ground_truth_times.empty())
      task.ground_truth_times = task.dataset / s.ground_truth_times;
    plan.sequences.push_back(std::move(task));
  }
  for (const SequenceSpec& s : spec.sequences) {
    for (const ConfigSpec& c : spec.configs) {
      if (!c.runsOn(s.name)) continue;
      const int runs = c.runs > 0 ? c.runs : spec.runs;
      for (int run = 1; run <= runs; ++run) {
        plan.cells.push_back({s.name, c.name, run,
                              plan.out / "cells" / s.name / c.name / fmt::format("run-{}", run)});
      }
    }
  }
  return plan;
}

std::vector<std::string> cellCommand(const SweepSpec& spec, const SweepPlan& plan,
                                     const CellTask& cell) {
  const SequenceSpec& s = spec.sequence(cell.sequence);
  const SequenceTask& task = plan.sequence(cell.sequence);
  const ConfigSpec& c = spec.config(cell.config);
  const auto values = placeholders(s, task, c, cell);
  if (c.external()) return {"/bin/sh", "-c", fillTemplate(c.command, values)};
  std::vector<std::string> command = {plan.superdyna.string(),
                                      "run",
                                      "--dataset",
                                      s.dataset,
                                      "--path",
                                      task.dataset.string(),
                                      "--mode",
                                      c.mode,
                                      "--output",
                                      (cell.dir / "trajectory.txt").string(),
                                      "--stats",
                                      (cell.dir / "stats.json").string()};
  const fs::path config = cellConfigPath(c, cell);
  if (!config.empty()) command.insert(command.end(), {"--config", config.string()});
  if (c.deterministic) command.push_back("--deterministic");
  if (labelsKeypoints(s, c)) {
    command.insert(command.end(), {"--dynamic-log", (cell.dir / "decisions.csv").string()});
  }
  for (const std::string& a : s.run_args)
    command.push_back(fillTemplate(a, values));
  for (const std::string& a : c.args)
    command.push_back(fillTemplate(a, values));
  return command;
}

std::string cellHash(const SweepSpec& spec, const SweepPlan& plan, const CellTask& cell) {
  const ConfigSpec& c = spec.config(cell.config);
  const SequenceTask& task = plan.sequence(cell.sequence);
  return fingerprint(shellQuote(cellCommand(spec, plan, cell)) + "\n" + cellConfigText(c) + "\n" +
                     task.hash + "\n" + c.trajectory + c.trajectory_format + c.time_unit +
                     c.alignment());
}

bool sequenceNeeded(const SequenceTask& task) {
  if (task.simulate.empty()) return false;
  if (!fs::exists(task.marker)) return true;
  std::ifstream in(task.marker);
  const nlohmann::json marker = nlohmann::json::parse(in, nullptr, false);
  return !marker.is_object() || marker.value("hash", "") != task.hash;
}

bool cellNeeded(const SweepSpec& spec, const SweepPlan& plan, const CellTask& cell,
                bool rerun_failed) {
  const fs::path file = cell.dir / kResultFile;
  if (!fs::exists(file)) return true;
  try {
    const CellResult done = readCellResult(file);
    return done.cell_hash != cellHash(spec, plan, cell) || (rerun_failed && !done.ok);
  } catch (const InputError&) {
    return true;  // a damaged marker: run the cell again
  }
}

void prepareSequence(const SweepPlan& plan, const SequenceTask& task, const std::string& revision) {
  if (!sequenceNeeded(task)) return;
  fs::remove(task.marker);
  fs::remove_all(task.dataset);  // a simulation killed halfway
  fs::create_directories(task.dataset.parent_path());
  const fs::path log = task.marker.parent_path() / (task.name + ".log");
  fs::remove(log);
  const ProcessResult p = runProcess(task.simulate, log, plan.spec_dir);
  if (!p.ok()) {
    throw InputError(InputLocation(log), fmt::format("simulating sequence '{}' failed ({}):\n{}",
                                                     task.name, p.describe(), tailOfFile(log, 15)));
  }
  const nlohmann::json marker = {{"sequence", task.name},    {"hash", task.hash},
                                 {"command", task.simulate}, {"git_revision", revision},
                                 {"machine", machine()},     {"wall_s", p.wall_s},
                                 {"finished", utcNow()}};
  writeText(task.marker, marker.dump(2) + "\n");
}

CellResult runCell(const SweepSpec& spec, const SweepPlan& plan, const CellTask& cell,
                   const std::string& revision) {
  const SequenceTask& task = plan.sequence(cell.sequence);
  if (sequenceNeeded(task)) {
    throw InputError(
        fmt::format("cell {}: sequence '{}' is not simulated yet", cell.id(), cell.sequence));
  }
  const ConfigSpec& c = spec.config(cell.config);
  fs::remove_all(cell.dir);  // what a killed attempt left
  fs::create_directories(cell.dir);
  if (!c.set.empty()) writeText(cellConfigPath(c, cell), cellConfigText(c));
  const std::vector<std::string> command = cellCommand(spec, plan, cell);
  CellResult result;
  result.sequence = cell.sequence;
  result.config = cell.config;
  result.run = cell.run;
  result.cell_hash = cellHash(spec, plan, cell);
  writeCellRecord(cell, command, result.cell_hash, revision);
  const ProcessResult p =
      runProcess(command, cell.dir / "log.txt", c.external() ? cell.dir : plan.spec_dir);
  result.wall_s = p.wall_s;
  result.cpu_s = p.cpu_s;
  result.peak_rss_mb = p.peak_rss_mb;
  try {
    if (!p.ok())
      throw InputError(p.describe() + "; the log ends:\n" + tailOfFile(cell.dir / "log.txt", 8));
    readRunStats(cell.dir / "stats.json", result);
    scoreCell(spec, plan, cell, result);
    scoreDecisions(cell, task, result);
    result.ok = true;
  } catch (const std::exception& e) {
    result.ok = false;
    result.error = e.what();
  }
  writeText(cell.dir / kResultFile, toJson(result).dump(2) + "\n");
  return result;
}

std::vector<CellResult> collectResults(const SweepSpec& spec, const SweepPlan& plan) {
  std::vector<CellResult> results;
  for (const CellTask& cell : plan.cells) {
    const fs::path file = cell.dir / kResultFile;
    if (!fs::exists(file)) continue;
    CellResult result = readCellResult(file);
    if (result.cell_hash == cellHash(spec, plan, cell)) results.push_back(std::move(result));
  }
  return results;
}

}  // namespace superdyna::sweep
