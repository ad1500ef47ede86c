#pragma once
// The two SVG charts of a sweep report besides the top views (eval/plot.h): a line chart (ATE
// over time, one line per config) and horizontal stacked bars (time per pipeline stage). Plain
// SVG 1.1 that browsers, Inkscape and LaTeX's svg package read.

#include <filesystem>
#include <string>
#include <vector>

namespace superdyna::sweep {

struct LineSeries {
  std::string label;
  std::vector<double> x;
  std::vector<double> y;
};

/// Axes from 0 (y) and the data's x range, ticks at 1-2-5 steps, a legend; InputError when the
/// file cannot be written or no series has a point.
void writeLineChart(const std::filesystem::path& file, const std::string& title,
                    const std::string& x_label, const std::string& y_label,
                    const std::vector<LineSeries>& series);

struct StackedBar {
  std::string label;           ///< The bar's name (a config).
  std::vector<double> values;  ///< One per segment name, >= 0.
};

/// One horizontal bar per entry, segments in `segment_names` order and colours, a legend.
void writeStackedBars(const std::filesystem::path& file, const std::string& title,
                      const std::string& value_label, const std::vector<std::string>& segment_names,
                      const std::vector<StackedBar>& bars);

}  // namespace superdyna::sweep
