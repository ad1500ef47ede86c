#include "superdyna/sweep/report_html.h"

#include <fmt/format.h>

#include <fstream>
#include <sstream>

#include "superdyna/core/atomic_file.h"
#include "superdyna/core/error.h"
#include "superdyna/eval/plot.h"
#include "superdyna/sweep/charts.h"

namespace superdyna::sweep {

namespace fs = std::filesystem;

namespace {

constexpr int kOverlaysPerSequence = 2;

/// The associated poses of a cell's evaluation (pose_errors.csv).
struct PoseRows {
  std::vector<double> t_s;
  std::vector<Eigen::Vector3d> gt, est;
  std::vector<double> error_m;
};

PoseRows readPoseErrors(const fs::path& file) {
  PoseRows rows;
  std::ifstream in(file);
  std::string line;
  std::getline(in, line);  // header
  while (std::getline(in, line)) {
    std::istringstream fields(line);
    std::vector<double> v;
    for (std::string f; std::getline(fields, f, ',');)
      v.push_back(std::stod(f));
    if (v.size() < 8) throw InputError(InputLocation(file), "a row has fewer than 8 columns");
    rows.t_s.push_back(v[0]);
    rows.gt.emplace_back(v[1], v[2], v[3]);
    rows.est.emplace_back(v[4], v[5], v[6]);
    rows.error_m.push_back(v[7]);
  }
  return rows;
}

/// The first successful run of a group, or none.
const CellResult* firstOk(const CellGroup& g) {
  const auto ok = g.ok();
  return ok.empty() ? nullptr : ok.front();
}

fs::path cellDir(const SweepPlan& plan, const CellResult& r) {
  for (const CellTask& c : plan.cells) {
    if (c.sequence == r.sequence && c.config == r.config && c.run == r.run) return c.dir;
  }
  throw InputError(fmt::format("no cell {}/{}/run-{} in the plan", r.sequence, r.config, r.run));
}

std::string figure(const std::string& image, const std::string& caption) {
  return fmt::format("<figure><img src=\"{}\" alt=\"{}\"><figcaption>{}</figcaption></figure>\n",
                     eval::escapeXml(image), eval::escapeXml(caption), eval::escapeXml(caption));
}

/// Top view and ATE over time of one sequence; empty when no config has a successful run.
std::string sequencePlots(const ReportContext& c, const std::string& sequence,
                          const fs::path& dir) {
  std::vector<eval::PlotSeries> estimates;
  std::vector<LineSeries> errors;
  eval::PlotSeries gt{"ground truth", {}};
  for (const CellGroup& g : c.groups) {
    const CellResult* r = g.sequence == sequence ? firstOk(g) : nullptr;
    if (r == nullptr) continue;
    const PoseRows rows = readPoseErrors(cellDir(c.plan, *r) / "pose_errors.csv");
    if (rows.t_s.empty()) continue;
    if (gt.positions.size() < rows.gt.size()) gt.positions = rows.gt;
    estimates.push_back({g.config, rows.est});
    LineSeries line{g.config, {}, {}};
    for (std::size_t i = 0; i < rows.t_s.size(); ++i) {
      line.x.push_back(rows.t_s[i] - rows.t_s.front());
      line.y.push_back(100.0 * rows.error_m[i]);
    }
    errors.push_back(std::move(line));
  }
  if (estimates.empty()) return "<p>No successful run.</p>\n";
  const std::string top = "plots/" + sequence + "_top.svg";
  const std::string ate = "plots/" + sequence + "_ate.svg";
  eval::PlotOptions options;
  options.title = sequence + ": top view";
  eval::writeTopViewPlot(dir / top, gt, estimates, options);
  writeLineChart(dir / ate, sequence + ": ATE over time (first run of each config)",
                 "time since the first evaluated pose [s]", "position error [cm]", errors);
  return "<div class=\"row\">" + figure(top, sequence + ": trajectories in the ground plane") +
         figure(ate, sequence + ": ATE over time") + "</div>\n";
}

std::string timingPlot(const ReportContext& c, const fs::path& dir) {
  std::vector<std::string> stages;
  std::vector<StackedBar> bars;
  for (const ConfigSpec& config : c.spec.configs) {
    std::map<std::string, std::pair<double, int>> sums;
    for (const CellGroup& g : c.groups) {
      if (g.config != config.name) continue;
      for (const CellResult* r : g.ok()) {
        for (const auto& [stage, ms] : r->stage_ms) {
          if (std::find(stages.begin(), stages.end(), stage) == stages.end())
            stages.push_back(stage);
          sums[stage].first += ms;
          ++sums[stage].second;
        }
      }
    }
    if (sums.empty()) continue;
    StackedBar bar{config.name, {}};
    for (const std::string& s : stages) {
      bar.values.push_back(sums.count(s) ? sums[s].first / sums[s].second : 0.0);
    }
    bars.push_back(std::move(bar));
  }
  if (bars.empty()) return "<p>No config reported its stage times (external systems do not).</p>\n";
  for (StackedBar& b : bars)
    b.values.resize(stages.size(), 0.0);
  writeStackedBars(dir / "plots/timing.svg", "Mean time per frame by pipeline stage",
                   "ms per frame (stages of one thread add up; threads overlap)", stages, bars);
  return figure("plots/timing.svg",
                "time per frame by pipeline stage, mean over sequences and runs");
}

std::string overlayImages(const ReportContext& c, const fs::path& dir) {
  std::string html;
  for (const CellGroup& g : c.groups) {
    const CellResult* r = firstOk(g);
    if (r == nullptr) continue;
    const fs::path overlay = cellDir(c.plan, *r) / "overlay";
    if (!fs::is_directory(overlay)) continue;
    std::vector<fs::path> images;
    for (const auto& entry : fs::directory_iterator(overlay)) {
      const std::string ext = entry.path().extension().string();
      if (ext == ".png" || ext == ".jpg") images.push_back(entry.path());
    }
    std::sort(images.begin(), images.end());
    for (int k = 0; k < kOverlaysPerSequence && k < static_cast<int>(images.size()); ++k) {
      const std::size_t pick = images.size() * (2 * k + 1) / (2 * kOverlaysPerSequence);
      const std::string name =
          fmt::format("overlays/{}_{}_{}", g.sequence, g.config, images[pick].filename().string());
      fs::create_directories(dir / "overlays");
      fs::copy_file(images[pick], dir / name, fs::copy_options::overwrite_existing);
      html += figure(
          name, fmt::format("{} / {}: {}", g.sequence, g.config, images[pick].filename().string()));
    }
  }
  return html.empty() ? ""
                      : "<h2 id=\"decisions\">Moving-object decisions</h2>\n<div class=\"row\">" +
                            html + "</div>\n";
}

std::string tableSection(const std::vector<TableText>& tables) {
  std::string html = "<h2 id=\"tables\">Tables</h2>\n";
  for (const TableText& t : tables) {
    html += fmt::format("<h3 id=\"table-{}\">{}</h3>\n{}<p class=\"files\">{}.md, {}.csv</p>\n",
                        eval::escapeXml(t.name), eval::escapeXml(t.title),
                        markdownTableToHtml(t.markdown), eval::escapeXml(t.name),
                        eval::escapeXml(t.name));
  }
  return html;
}

std::string header(const ReportContext& c) {
  std::size_t ok = 0, failed = 0;
  for (const CellGroup& g : c.groups) {
    ok += g.ok().size();
    failed += g.runs.size() - g.ok().size();
  }
  return fmt::format(
      "<h1>Sweep {}</h1>\n<p>{} sequences x {} configs x {} runs: {} cells finished ({} "
      "failed) of {}. Spec <code>{}</code>; built from git revision <code>{}</code>. Each cell's "
      "command line, revision, definition hash and machine are in "
      "<code>cells/&lt;sequence&gt;/&lt;config&gt;/run-&lt;k&gt;/cell.json</code>.</p>\n"
      "<p><a href=\"#tables\">Tables</a> · <a href=\"#trajectories\">Trajectories</a> · "
      "<a href=\"#timing\">Timing</a></p>\n",
      eval::escapeXml(c.spec.name), c.spec.sequences.size(), c.spec.configs.size(), c.spec.runs,
      ok + failed, failed, c.plan.cells.size(), eval::escapeXml(c.spec.file.string()),
      eval::escapeXml(c.revision));
}

constexpr const char* kStyle = R"(<style>
body { font-family: sans-serif; margin: 2em; color: #222; }
table { border-collapse: collapse; margin: 0.5em 0; font-size: 0.9em; }
th, td { border: 1px solid #ccc; padding: 0.25em 0.6em; text-align: right; }
th { background: #f2f2f2; }
td:first-child, th:first-child { text-align: left; }
.row { display: flex; flex-wrap: wrap; gap: 1em; }
figure { margin: 0; } figure img { width: 600px; max-width: 46vw; border: 1px solid #ddd; }
figcaption { font-size: 0.85em; color: #555; }
.files { font-size: 0.8em; color: #777; }
</style>
)";

// Marks the page for tests and for readers: every image loaded, or which did not.
constexpr const char* kStatusScript = R"(<script>
window.addEventListener('error', function (e) {
  document.body.dataset.status = 'script error: ' + e.message;
});
window.addEventListener('load', function () {
  if (document.body.dataset.status) return;
  var images = Array.prototype.slice.call(document.images);
  var broken = images.filter(function (i) { return !i.complete || i.naturalWidth === 0; });
  document.body.dataset.status = broken.length === 0 ? 'ok ' + images.length + ' images'
      : 'broken images: ' + broken.map(function (i) { return i.getAttribute('src'); }).join(' ');
});
</script>
)";

}  // namespace

std::string markdownTableToHtml(const std::string& markdown) {
  std::istringstream lines(markdown);
  std::string html = "<table>\n", line;
  int row = 0;
  while (std::getline(lines, line)) {
    if (line.size() < 2 || line.front() != '|') continue;
    if (row++ == 1) continue;  // the | --- | separator
    const char* cell = row == 1 ? "th" : "td";
    html += "<tr>";
    std::size_t start = 1;
    for (std::size_t bar = line.find(" |", start); bar != std::string::npos;
         bar = line.find(" |", start)) {
      std::string field = line.substr(start, bar - start);
      if (!field.empty() && field.front() == ' ') field.erase(0, 1);
      html += fmt::format("<{0}>{1}</{0}>", cell, eval::escapeXml(field));
      start = bar + 2;
    }
    html += "</tr>\n";
  }
  return html + "</table>\n";
}

fs::path writeHtmlReport(const ReportContext& c, const fs::path& dir) {
  fs::create_directories(dir / "plots");
  std::string body =
      header(c) + tableSection(c.tables) + "<h2 id=\"trajectories\">Trajectories</h2>\n";
  for (const SequenceSpec& s : c.spec.sequences) {
    body += fmt::format("<h3>{}</h3>\n", eval::escapeXml(s.name)) + sequencePlots(c, s.name, dir);
  }
  body += "<h2 id=\"timing\">Timing</h2>\n" + timingPlot(c, dir) + overlayImages(c, dir);
  const fs::path page = dir / "index.html";
  AtomicFile out(page);
  out.stream() << "<!DOCTYPE html>\n<html lang=\"en\">\n<head>\n<meta charset=\"utf-8\">\n"
               << fmt::format("<title>Sweep {}</title>\n", eval::escapeXml(c.spec.name)) << kStyle
               << "</head>\n<body>\n"
               << body << kStatusScript << "</body>\n</html>\n";
  out.commit();
  return page;
}

}  // namespace superdyna::sweep
