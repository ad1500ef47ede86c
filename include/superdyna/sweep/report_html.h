#pragma once
// The static HTML page of a sweep (DIR/report/index.html, its images beside it): the tables, a
// top view per sequence with every config's first successful run over the ground truth (in the
// ground plane, eval/plot.h), the ATE of those runs over time, time per pipeline stage, and the
// moving-object overlay images of cells that wrote them (`--overlay {out}/overlay`). No network,
// no external script: it opens from the file system. A small script marks the page
// (<body data-status="ok N images">) once every image has loaded, or names the broken ones or a
// script error; the report test reads that mark from headless Chromium.

#include <filesystem>
#include <vector>

#include "superdyna/sweep/sweep.h"
#include "superdyna/sweep/tables.h"

namespace superdyna::sweep {

struct ReportContext {
  const SweepSpec& spec;
  const SweepPlan& plan;
  const std::vector<CellGroup>& groups;
  const std::vector<TableText>& tables;
  std::string revision;
};

/// Writes the page and its images under `dir` (created); returns the page's path.
std::filesystem::path writeHtmlReport(const ReportContext& context,
                                      const std::filesystem::path& dir);

/// A Markdown table (as tables.h writes them) as an HTML <table>.
std::string markdownTableToHtml(const std::string& markdown);

}  // namespace superdyna::sweep
