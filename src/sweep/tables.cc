#include "superdyna/sweep/tables.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <algorithm>
#include <cmath>
#include <set>

#include "superdyna/core/atomic_file.h"
#include "superdyna/core/error.h"
#include "superdyna/eval/multi_run.h"

namespace superdyna::sweep {

namespace fs = std::filesystem;

namespace {

using Getter = std::function<double(const CellResult&)>;

std::vector<double> values(const CellGroup& group, const Getter& get) {
  std::vector<double> out;
  for (const CellResult* r : group.ok()) {
    const double v = get(*r);
    if (std::isfinite(v)) out.push_back(v);
  }
  return out;
}

double median(const CellGroup& group, const Getter& get) {
  const std::vector<double> v = values(group, get);
  return v.empty() ? kNotMeasured : eval::summarizeRunValues(v).median;
}

double maximum(const CellGroup& group, const Getter& get) {
  const std::vector<double> v = values(group, get);
  return v.empty() ? kNotMeasured : *std::max_element(v.begin(), v.end());
}

/// A failed run is part of the result: "0.78 cm (1 of 3 failed)".
std::string withFailures(const CellGroup& group, const std::string& text) {
  const std::size_t failed = group.runs.size() - group.ok().size();
  if (group.runs.empty()) return "-";
  if (failed == 0) return text;
  if (failed == group.runs.size()) return fmt::format("failed ({} of {})", failed, failed);
  return fmt::format("{} ({} of {} failed)", text, failed, group.runs.size());
}

std::string number(double value, int decimals) {
  return std::isfinite(value) ? fmt::format("{:.{}f}", value, decimals) : "-";
}

std::string ateMeanCi(const CellGroup& group) {
  const std::vector<double> v = values(group, [](const CellResult& r) { return r.ate_rmse_m; });
  if (v.empty()) return "-";
  const eval::RunStatistics s = eval::summarizeRunValues(v);
  if (v.size() < 2) return formatMetres(s.mean);
  // The interval in the mean's unit, so that "1.19 ± 0.46 cm" reads as one quantity.
  const std::string mean = formatMetres(s.mean);
  const bool cm = mean.ends_with(" cm");
  return fmt::format("{} ± {}", mean.substr(0, mean.size() - (cm ? 3 : 2)),
                     cm ? fmt::format("{:.2f} cm", 100.0 * s.ci95_halfwidth)
                        : fmt::format("{:.3f} m", s.ci95_halfwidth));
}

std::string ateRuns(const CellGroup& group) {
  std::vector<std::string> texts;
  for (const CellResult& r : group.runs)
    texts.push_back(r.ok ? formatMetres(r.ate_rmse_m) : "failed");
  return texts.empty() ? "-" : fmt::format("{}", fmt::join(texts, " / "));
}

Metric medianMetric(std::string name, std::string label, Getter get, int decimals) {
  auto value = [get](const CellGroup& g) { return median(g, get); };
  auto text = [value, decimals](const CellGroup& g) {
    return withFailures(g, number(value(g), decimals));
  };
  return {std::move(name), std::move(label), value, text};
}

std::vector<Metric> makeMetrics() {
  const Getter ate = [](const CellResult& r) { return r.ate_rmse_m; };
  std::vector<Metric> m;
  m.push_back(
      {"ate_median", "ATE RMSE, median of runs",
       [ate](const CellGroup& g) { return median(g, ate); },
       [ate](const CellGroup& g) { return withFailures(g, formatMetres(median(g, ate))); }});
  m.push_back({"ate_mean_ci", "ATE RMSE, mean ± 95 % CI",
               [](const CellGroup& g) {
                 const auto v = values(g, [](const CellResult& r) { return r.ate_rmse_m; });
                 return v.empty() ? kNotMeasured : eval::summarizeRunValues(v).mean;
               },
               [](const CellGroup& g) { return withFailures(g, ateMeanCi(g)); }});
  m.push_back({"ate_runs", "ATE RMSE of each run",
               [ate](const CellGroup& g) { return median(g, ate); }, ateRuns});
  m.push_back(medianMetric(
      "rpe_trans_median", "RPE translation RMSE, median",
      [](const CellResult& r) { return r.rpe_trans; }, 4));
  m.push_back(medianMetric(
      "rpe_rot_median", "RPE rotation RMSE, median", [](const CellResult& r) { return r.rpe_rot; },
      4));
  m.push_back(medianMetric(
      "lost_frames", "lost frames, median", [](const CellResult& r) { return r.lost_frames; }, 0));
  m.push_back(medianMetric(
      "map_resets", "map resets, median", [](const CellResult& r) { return r.map_resets; }, 0));
  m.push_back(medianMetric(
      "fps", "FPS (wall clock), median", [](const CellResult& r) { return r.fps; }, 1));
  m.push_back(medianMetric(
      "cpu_ms_per_frame", "CPU ms per frame, median",
      [](const CellResult& r) { return r.cpuMsPerFrame(); }, 1));
  const auto percent = [](std::string name, std::string label, Getter get) {
    auto value = [get](const CellGroup& g) { return median(g, get); };
    auto text = [value](const CellGroup& g) {
      const double v = value(g);
      return withFailures(g, std::isfinite(v) ? fmt::format("{:.1f} %", 100.0 * v) : "-");
    };
    return Metric{std::move(name), std::move(label), value, text};
  };
  m.push_back(percent("moving_precision", "precision of 'moving', median",
                      [](const CellResult& r) { return r.moving_precision; }));
  m.push_back(percent("moving_recall", "recall of 'moving', median",
                      [](const CellResult& r) { return r.moving_recall; }));
  m.push_back(percent("static_kept", "features kept on standing objects, median",
                      [](const CellResult& r) { return r.static_kept; }));
  const Getter rss = [](const CellResult& r) { return r.peak_rss_mb; };
  m.push_back({"peak_rss_mb", "peak memory [MB], largest run",
               [rss](const CellGroup& g) { return maximum(g, rss); },
               [rss](const CellGroup& g) { return withFailures(g, number(maximum(g, rss), 0)); }});
  return m;
}

std::string csvField(const std::string& text) {
  if (text.find_first_of(",\"\n") == std::string::npos) return text;
  std::string quoted = "\"";
  for (char ch : text)
    quoted += ch == '"' ? std::string("\"\"") : std::string(1, ch);
  return quoted + "\"";
}

std::string csvNumber(double value) {
  return std::isfinite(value) ? fmt::format("{:.9g}", value) : "";
}

/// Markdown and CSV built side by side, row by row.
class TableBuilder {
 public:
  explicit TableBuilder(const std::vector<std::string>& header) : columns_(header.size()) {
    markdown_ = fmt::format("| {} |\n|{}\n", fmt::join(header, " | "), repeat(" --- |"));
    std::vector<std::string> fields;
    for (const std::string& h : header)
      fields.push_back(csvField(h));
    csv_ = fmt::format("{}\n", fmt::join(fields, ","));
  }
  void row(const std::vector<std::string>& texts, const std::vector<std::string>& csv) {
    markdown_ += fmt::format("| {} |\n", fmt::join(texts, " | "));
    std::vector<std::string> fields;
    for (const std::string& f : csv)
      fields.push_back(csvField(f));
    csv_ += fmt::format("{}\n", fmt::join(fields, ","));
  }
  TableText done(std::string name, std::string title) const {
    return {std::move(name), std::move(title), markdown_, csv_};
  }

 private:
  std::string repeat(const std::string& cell) const {
    std::string out;
    for (std::size_t i = 0; i < columns_; ++i)
      out += cell;
    return out;
  }
  std::size_t columns_;
  std::string markdown_;
  std::string csv_;
};

const CellGroup* findGroup(const std::vector<CellGroup>& groups, const std::string& sequence,
                           const std::string& config) {
  for (const CellGroup& g : groups) {
    if (g.sequence == sequence && g.config == config) return &g;
  }
  return nullptr;
}

std::string unitsOf(const std::vector<CellGroup>& groups) {
  for (const CellGroup& g : groups) {
    for (const CellResult* r : g.ok()) {
      if (!r->rpe_trans_unit.empty())
        return fmt::format("{}, {}", r->rpe_trans_unit, r->rpe_rot_unit);
    }
  }
  return "-";
}

}  // namespace

std::vector<const CellResult*> CellGroup::ok() const {
  std::vector<const CellResult*> out;
  for (const CellResult& r : runs) {
    if (r.ok) out.push_back(&r);
  }
  return out;
}

const std::vector<Metric>& metrics() {
  static const std::vector<Metric> all = makeMetrics();
  return all;
}

const Metric& metric(const std::string& name) {
  for (const Metric& m : metrics()) {
    if (m.name == name) return m;
  }
  throw OptionError("metric", fmt::format("unknown metric '{}'", name));
}

std::string formatMetres(double metres) {
  if (!std::isfinite(metres)) return "-";
  if (std::abs(metres) < 1.0) return fmt::format("{:.2f} cm", 100.0 * metres);
  return fmt::format("{:.3f} m", metres);
}

std::vector<CellGroup> groupResults(const SweepSpec& spec, const std::vector<CellResult>& results) {
  std::vector<CellGroup> groups;
  for (const SequenceSpec& s : spec.sequences) {
    for (const ConfigSpec& c : spec.configs) {
      if (!c.runsOn(s.name)) continue;
      CellGroup group{s.name, c.name, {}};
      for (const CellResult& r : results) {
        if (r.sequence == s.name && r.config == c.name) group.runs.push_back(r);
      }
      std::sort(group.runs.begin(), group.runs.end(),
                [](const CellResult& a, const CellResult& b) { return a.run < b.run; });
      groups.push_back(std::move(group));
    }
  }
  return groups;
}

TableText accuracyTable(const std::vector<CellGroup>& groups) {
  TableBuilder table({"sequence", "config", "runs ok", "ATE median", "ATE mean ± 95 % CI",
                      "ATE min", "ATE max", "RPE trans median", "RPE rot median", "lost frames",
                      "map resets"});
  const Getter ate = [](const CellResult& r) { return r.ate_rmse_m; };
  for (const CellGroup& g : groups) {
    const std::vector<double> v = values(g, ate);
    const double lo = v.empty() ? kNotMeasured : *std::min_element(v.begin(), v.end());
    const double hi = v.empty() ? kNotMeasured : *std::max_element(v.begin(), v.end());
    std::vector<std::string> texts = {g.sequence, g.config,
                                      fmt::format("{} / {}", g.ok().size(), g.runs.size())};
    std::vector<std::string> csv = texts;
    for (const char* name : {"ate_median", "ate_mean_ci"}) {
      texts.push_back(metric(name).text(g));
      csv.push_back(csvNumber(metric(name).value(g)));
    }
    texts.push_back(formatMetres(lo));
    texts.push_back(formatMetres(hi));
    csv.push_back(csvNumber(lo));
    csv.push_back(csvNumber(hi));
    for (const char* name : {"rpe_trans_median", "rpe_rot_median", "lost_frames", "map_resets"}) {
      texts.push_back(metric(name).text(g));
      csv.push_back(csvNumber(metric(name).value(g)));
    }
    table.row(texts, csv);
  }
  return table.done("accuracy", fmt::format("Accuracy per sequence and config (ATE: RMSE after "
                                            "alignment; RPE units: {})",
                                            unitsOf(groups)));
}

TableText speedTable(const std::vector<CellGroup>& groups) {
  TableBuilder table({"sequence", "config", "runs ok", "FPS median", "CPU ms per frame median",
                      "peak memory [MB]"});
  for (const CellGroup& g : groups) {
    std::vector<std::string> texts = {g.sequence, g.config,
                                      fmt::format("{} / {}", g.ok().size(), g.runs.size())};
    std::vector<std::string> csv = texts;
    for (const char* name : {"fps", "cpu_ms_per_frame", "peak_rss_mb"}) {
      texts.push_back(metric(name).text(g));
      csv.push_back(csvNumber(metric(name).value(g)));
    }
    table.row(texts, csv);
  }
  return table.done("speed",
                    "Speed: wall-clock FPS, CPU time of the process and its children, "
                    "peak resident memory");
}

std::optional<TableText> decisionsTable(const std::vector<CellGroup>& groups) {
  TableBuilder table(
      {"sequence", "config", "runs ok", "precision of 'moving'", "recall", "static features kept"});
  bool any = false;
  for (const CellGroup& g : groups) {
    if (!std::isfinite(metric("moving_precision").value(g)) &&
        !std::isfinite(metric("static_kept").value(g))) {
      continue;
    }
    std::vector<std::string> texts = {g.sequence, g.config,
                                      fmt::format("{} / {}", g.ok().size(), g.runs.size())};
    std::vector<std::string> csv = texts;
    for (const char* name : {"moving_precision", "moving_recall", "static_kept"}) {
      texts.push_back(metric(name).text(g));
      csv.push_back(csvNumber(metric(name).value(g)));
    }
    table.row(texts, csv);
    any = true;
  }
  if (!any) return std::nullopt;
  return table.done("decisions",
                    "Moving-object decisions per object-frame (objects with at least "
                    "8 matched features; median of runs)");
}

TableText timingTable(const SweepSpec& spec, const std::vector<CellGroup>& groups) {
  std::vector<std::string> stages;
  for (const CellGroup& g : groups) {
    for (const CellResult* r : g.ok()) {
      for (const auto& [stage, ms] : r->stage_ms) {
        if (std::find(stages.begin(), stages.end(), stage) == stages.end()) stages.push_back(stage);
      }
    }
  }
  std::vector<std::string> header = {"config", "runs"};
  for (const std::string& s : stages)
    header.push_back(s + " [ms]");
  TableBuilder table(header);
  for (const ConfigSpec& c : spec.configs) {
    std::map<std::string, std::vector<double>> per_stage;
    std::size_t runs = 0;
    for (const CellGroup& g : groups) {
      if (g.config != c.name) continue;
      for (const CellResult* r : g.ok()) {
        ++runs;
        for (const auto& [stage, ms] : r->stage_ms)
          per_stage[stage].push_back(ms);
      }
    }
    std::vector<std::string> texts = {c.name, std::to_string(runs)};
    std::vector<std::string> csv = texts;
    for (const std::string& s : stages) {
      const auto& v = per_stage[s];
      const double mean = v.empty() ? kNotMeasured : eval::summarizeRunValues(v).mean;
      texts.push_back(number(mean, 2));
      csv.push_back(csvNumber(mean));
    }
    table.row(texts, csv);
  }
  return table.done("timing",
                    "Mean time per frame of each pipeline stage (ms), over every "
                    "sequence and run of a config");
}

TableText matrixTable(const SweepSpec& spec, const TableSpec& t,
                      const std::vector<CellGroup>& groups) {
  const Metric& m = metric(t.metric);
  std::vector<std::string> sequences = t.sequences, configs = t.configs;
  if (sequences.empty()) {
    for (const SequenceSpec& s : spec.sequences)
      sequences.push_back(s.name);
  }
  if (configs.empty()) {
    for (const ConfigSpec& c : spec.configs)
      configs.push_back(c.name);
  }
  const auto& rows = t.rows_are_configs ? configs : sequences;
  const auto& columns = t.rows_are_configs ? sequences : configs;
  std::vector<std::string> header = {t.rows_are_configs ? "config" : "sequence"};
  header.insert(header.end(), columns.begin(), columns.end());
  TableBuilder table(header);
  for (const std::string& row : rows) {
    std::vector<std::string> texts = {row}, csv = {row};
    for (const std::string& column : columns) {
      const CellGroup* g =
          t.rows_are_configs ? findGroup(groups, column, row) : findGroup(groups, row, column);
      texts.push_back(g ? m.text(*g) : "");
      csv.push_back(g ? csvNumber(m.value(*g)) : "");
    }
    table.row(texts, csv);
  }
  return table.done(t.name, fmt::format("{} ({})", t.title, m.label));
}

std::vector<TableText> allTables(const SweepSpec& spec, const std::vector<CellGroup>& groups) {
  std::vector<TableText> tables;
  tables.push_back(matrixTable(spec, {"ate", "ATE", "ate_median", false, {}, {}}, groups));
  tables.push_back(accuracyTable(groups));
  if (auto decisions = decisionsTable(groups)) tables.push_back(std::move(*decisions));
  for (const TableSpec& t : spec.tables)
    tables.push_back(matrixTable(spec, t, groups));
  tables.push_back(speedTable(groups));
  tables.push_back(timingTable(spec, groups));
  return tables;
}

void writeTables(const std::vector<TableText>& tables, const fs::path& dir) {
  fs::create_directories(dir);
  std::string all;
  for (const TableText& t : tables) {
    for (const auto& [extension, text] : {std::pair{".md", t.markdown}, std::pair{".csv", t.csv}}) {
      AtomicFile file(dir / (t.name + extension));
      file.stream() << text;
      file.commit();
    }
    all += fmt::format("### {}\n\n{}\n", t.title, t.markdown);
  }
  AtomicFile file(dir / "tables.md");
  file.stream() << all;
  file.commit();
}

}  // namespace superdyna::sweep
