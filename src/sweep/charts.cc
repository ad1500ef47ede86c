#include "superdyna/sweep/charts.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>

#include "superdyna/core/atomic_file.h"
#include "superdyna/core/error.h"
#include "superdyna/eval/plot.h"

namespace superdyna::sweep {

namespace {

// matplotlib's tab10, as in the top views.
constexpr std::array<const char*, 10> kPalette = {"#1f77b4", "#ff7f0e", "#2ca02c", "#d62728",
                                                  "#9467bd", "#8c564b", "#e377c2", "#7f7f7f",
                                                  "#bcbd22", "#17becf"};
constexpr double kWidth = 900, kLeft = 80, kRight = 200, kTop = 45, kBottom = 55;

std::string text(double x, double y, const std::string& s, const char* anchor, int size = 12,
                 const std::string& extra = "") {
  return fmt::format(
      "<text x=\"{:.1f}\" y=\"{:.1f}\" text-anchor=\"{}\" font-size=\"{}\"{}>{}</text>\n", x, y,
      anchor, size, extra, eval::escapeXml(s));
}

std::string tickText(double value, double step) {
  const int decimals = step >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step) - 1e-9));
  return fmt::format("{:.{}f}", std::abs(value) < 0.5 * step ? 0.0 : value, decimals);
}

void save(const std::filesystem::path& file, double height, const std::string& body) {
  AtomicFile out(file);
  out.stream() << fmt::format(
      "<?xml version=\"1.0\" encoding=\"UTF-8\"?>\n<svg xmlns=\"http://www.w3.org/2000/svg\" "
      "width=\"{0:.0f}\" height=\"{1:.0f}\" viewBox=\"0 0 {0:.0f} {1:.0f}\" "
      "font-family=\"sans-serif\">\n<rect width=\"100%\" height=\"100%\" fill=\"white\"/>\n{2}"
      "</svg>\n",
      kWidth, height, body);
  out.commit();
}

std::string legend(const std::vector<std::string>& labels, double top) {
  std::string out;
  for (std::size_t k = 0; k < labels.size(); ++k) {
    const double y = top + 20.0 * static_cast<double>(k);
    out += fmt::format("<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"14\" height=\"10\" fill=\"{}\"/>\n",
                       kWidth - kRight + 15, y - 9, kPalette[k % kPalette.size()]);
    out += text(kWidth - kRight + 35, y, labels[k], "start");
  }
  return out;
}

}  // namespace

void writeLineChart(const std::filesystem::path& file, const std::string& title,
                    const std::string& x_label, const std::string& y_label,
                    const std::vector<LineSeries>& series) {
  double x_min = INFINITY, x_max = -INFINITY, y_max = 0.0;
  for (const LineSeries& s : series) {
    for (std::size_t i = 0; i < s.x.size() && i < s.y.size(); ++i) {
      x_min = std::min(x_min, s.x[i]);
      x_max = std::max(x_max, s.x[i]);
      y_max = std::max(y_max, s.y[i]);
    }
  }
  if (!std::isfinite(x_min)) throw InputError(InputLocation(file), "nothing to plot");
  if (x_max <= x_min) x_max = x_min + 1.0;
  if (y_max <= 0.0) y_max = 1.0;
  const double height = 420, area_w = kWidth - kLeft - kRight, area_h = height - kTop - kBottom;
  const double y_step = eval::niceTickStep(y_max, 5);
  y_max = std::ceil(y_max / y_step) * y_step;
  const auto px = [&](double x) { return kLeft + (x - x_min) / (x_max - x_min) * area_w; };
  const auto py = [&](double y) { return kTop + area_h - y / y_max * area_h; };
  std::string body = text(kWidth / 2, 25, title, "middle", 16);
  for (double y = 0.0; y <= y_max + 1e-9 * y_max; y += y_step) {
    body += fmt::format(
        "<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" "
        "stroke=\"#e1e1e1\"/>\n",
        kLeft, py(y), kLeft + area_w, py(y));
    body += text(kLeft - 8, py(y) + 4, tickText(y, y_step), "end");
  }
  const double x_step = eval::niceTickStep(x_max - x_min, 8);
  for (double x = std::ceil(x_min / x_step) * x_step; x <= x_max; x += x_step) {
    body += text(px(x), kTop + area_h + 18, tickText(x, x_step), "middle");
  }
  body += fmt::format(
      "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" "
      "fill=\"none\" stroke=\"black\"/>\n",
      kLeft, kTop, area_w, area_h);
  body += text(kLeft + area_w / 2, height - 12, x_label, "middle", 13);
  body += text(20, kTop + area_h / 2, y_label, "middle", 13,
               fmt::format(" transform=\"rotate(-90 20 {:.1f})\"", kTop + area_h / 2));
  std::vector<std::string> labels;
  for (std::size_t k = 0; k < series.size(); ++k) {
    std::string points;
    for (std::size_t i = 0; i < series[k].x.size() && i < series[k].y.size(); ++i) {
      points += fmt::format("{:.1f},{:.1f} ", px(series[k].x[i]), py(series[k].y[i]));
    }
    body +=
        fmt::format("<polyline fill=\"none\" stroke=\"{}\" stroke-width=\"1.5\" points=\"{}\"/>\n",
                    kPalette[k % kPalette.size()], points);
    labels.push_back(series[k].label);
  }
  save(file, height, body + legend(labels, kTop + 10));
}

void writeStackedBars(const std::filesystem::path& file, const std::string& title,
                      const std::string& value_label, const std::vector<std::string>& segment_names,
                      const std::vector<StackedBar>& bars) {
  if (bars.empty()) throw InputError(InputLocation(file), "nothing to plot");
  double total_max = 0.0;
  for (const StackedBar& b : bars) {
    double total = 0.0;
    for (double v : b.values)
      total += std::max(v, 0.0);
    total_max = std::max(total_max, total);
  }
  if (total_max <= 0.0) total_max = 1.0;
  const double bar_h = 22, gap = 10, left = 170;
  const double area_w = kWidth - left - kRight;
  const double area_h = static_cast<double>(bars.size()) * (bar_h + gap) + gap;
  const double height = kTop + area_h + kBottom;
  const double step = eval::niceTickStep(total_max, 6);
  const double x_max = std::ceil(total_max / step) * step;
  const auto px = [&](double v) { return left + v / x_max * area_w; };
  std::string body = text(kWidth / 2, 25, title, "middle", 16);
  for (double v = 0.0; v <= x_max + 1e-9 * x_max; v += step) {
    body += fmt::format(
        "<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" "
        "stroke=\"#e1e1e1\"/>\n",
        px(v), kTop, kTop + area_h);
    body += text(px(v), kTop + area_h + 18, tickText(v, step), "middle");
  }
  for (std::size_t b = 0; b < bars.size(); ++b) {
    const double y = kTop + gap + static_cast<double>(b) * (bar_h + gap);
    body += text(left - 8, y + bar_h * 0.7, bars[b].label, "end");
    double at = 0.0;
    for (std::size_t k = 0; k < bars[b].values.size(); ++k) {
      const double v = std::max(bars[b].values[k], 0.0);
      body += fmt::format(
          "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" "
          "fill=\"{}\"><title>{}: {:.2f}</title></rect>\n",
          px(at), y, px(at + v) - px(at), bar_h, kPalette[k % kPalette.size()],
          eval::escapeXml(segment_names[k]), v);
      at += v;
    }
  }
  body += text(left + area_w / 2, height - 12, value_label, "middle", 13);
  save(file, height, body + legend(segment_names, kTop + 10));
}

}  // namespace superdyna::sweep
