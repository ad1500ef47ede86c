#include "superdyna/eval/plot.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cctype>
#include <cmath>
#include <fstream>
#include <limits>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <optional>

#include "superdyna/core/error.h"

namespace superdyna::eval {
namespace {

// Layout in pixels: room for tick labels left and below, the title above.
constexpr double kMarginLeft = 80.0;
constexpr double kMarginRight = 30.0;
constexpr double kMarginTop = 50.0;
constexpr double kMarginBottom = 60.0;
constexpr double kPaddingFraction = 0.05;  // empty border around the data, per side
constexpr int kTargetTicks = 6;
constexpr double kMinStepPx = 0.5;  // closer points are not drawn: invisible, but bloat the SVG
constexpr int kMinImageSize = 200;
constexpr int kMaxImageSize = 20000;

struct Rgb {
  int r, g, b;
  std::string hex() const { return fmt::format("#{:02x}{:02x}{:02x}", r, g, b); }
  cv::Scalar bgr() const { return cv::Scalar(b, g, r); }
};

constexpr Rgb kGroundTruthColour{48, 48, 48};
constexpr Rgb kGridColour{225, 225, 225};
constexpr Rgb kBlack{0, 0, 0};
// The matplotlib "tab10" cycle: distinguishable, and familiar from evo's plots.
constexpr std::array<Rgb, 10> kPalette{{{31, 119, 180},
                                        {255, 127, 14},
                                        {44, 160, 44},
                                        {214, 39, 40},
                                        {148, 103, 189},
                                        {140, 86, 75},
                                        {227, 119, 194},
                                        {127, 127, 127},
                                        {188, 189, 34},
                                        {23, 190, 207}}};

enum class ImageFormat { kSvg, kPng };

/// A series ready to draw: pixel coordinates, colour, line width.
struct DrawnSeries {
  std::string label;
  std::vector<Eigen::Vector2d> pixels;
  Rgb colour;
  double line_width;
};

/// Maps metres to pixels with one scale for both axes (equal aspect), y pointing up.
struct Layout {
  double width = 0.0, height = 0.0;            // whole image
  double left = 0.0, top = 0.0;                // plot area origin
  double area_width = 0.0, area_height = 0.0;  // plot area size
  double px_per_m = 1.0;
  double x0 = 0.0, y0 = 0.0;  // metres at the plot area's left and bottom edges
  double tick_step_m = 1.0;
  std::string x_axis = "x", y_axis = "y";  // the plot plane's axes

  double pixelX(double x_m) const { return left + (x_m - x0) * px_per_m; }
  double pixelY(double y_m) const { return top + area_height - (y_m - y0) * px_per_m; }
  double x1() const { return x0 + area_width / px_per_m; }
  double y1() const { return y0 + area_height / px_per_m; }
};

std::string lowercase(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

ImageFormat formatFromExtension(const std::filesystem::path& file) {
  const std::string extension = lowercase(file.extension().string());
  if (extension == ".svg") return ImageFormat::kSvg;
  if (extension == ".png") return ImageFormat::kPng;
  throw OptionError("plot", fmt::format("'{}': unsupported image type '{}' (use .svg or .png)",
                                        file.string(), file.extension().string()));
}

Layout computeLayout(const std::vector<const PlotSeries*>& series, const PlotOptions& options) {
  double min_x = std::numeric_limits<double>::infinity(), max_x = -min_x;
  double min_y = min_x, max_y = max_x;
  for (const PlotSeries* s : series) {
    for (const Eigen::Vector3d& p : s->positions) {
      min_x = std::min(min_x, p.x());
      max_x = std::max(max_x, p.x());
      min_y = std::min(min_y, p.y());
      max_y = std::max(max_y, p.y());
    }
  }
  // A degenerate extent (one point, or motion along one axis) still needs a finite scale.
  const double largest = std::max({max_x - min_x, max_y - min_y});
  const double floor_span = largest > 0.0 ? 0.05 * largest : 1.0;
  const double span_x = std::max(max_x - min_x, floor_span) * (1.0 + 2.0 * kPaddingFraction);
  const double span_y = std::max(max_y - min_y, floor_span) * (1.0 + 2.0 * kPaddingFraction);

  Layout layout;
  layout.width = options.width;
  layout.height = options.height;
  layout.left = kMarginLeft;
  layout.top = kMarginTop;
  layout.area_width = options.width - kMarginLeft - kMarginRight;
  layout.area_height = options.height - kMarginTop - kMarginBottom;
  layout.px_per_m = std::min(layout.area_width / span_x, layout.area_height / span_y);
  layout.x0 = 0.5 * (min_x + max_x) - 0.5 * layout.area_width / layout.px_per_m;
  layout.y0 = 0.5 * (min_y + max_y) - 0.5 * layout.area_height / layout.px_per_m;
  layout.tick_step_m =
      niceTickStep(std::max(layout.x1() - layout.x0, layout.y1() - layout.y0), kTargetTicks);
  return layout;
}

/// Tick positions (metres) inside [from, to].
std::vector<double> ticks(double from, double to, double step) {
  std::vector<double> values;
  for (double k = std::ceil(from / step); k * step <= to; k += 1.0)
    values.push_back(k * step);
  return values;
}

std::string tickLabel(double value_m, double step_m) {
  const int decimals = step_m >= 1.0 ? 0 : static_cast<int>(std::ceil(-std::log10(step_m) - 1e-9));
  if (std::abs(value_m) < 0.5 * step_m) value_m = 0.0;  // no "-0"
  return fmt::format("{:.{}f}", value_m, decimals);
}

/// The series in the plane's coordinates: its two axes become x and y.
PlotSeries projectOnto(const PlotSeries& series, PlotPlane plane) {
  PlotSeries projected{series.label, {}};
  projected.positions.reserve(series.positions.size());
  for (const Eigen::Vector3d& p : series.positions) {
    switch (plane) {
      case PlotPlane::kXZ:
        projected.positions.emplace_back(p.x(), p.z(), 0.0);
        break;
      case PlotPlane::kYZ:
        projected.positions.emplace_back(p.y(), p.z(), 0.0);
        break;
      default:
        projected.positions.emplace_back(p.x(), p.y(), 0.0);
    }
  }
  return projected;
}

std::vector<Eigen::Vector2d> toPixels(const PlotSeries& series, const Layout& layout) {
  std::vector<Eigen::Vector2d> pixels;
  for (const Eigen::Vector3d& p : series.positions) {
    const Eigen::Vector2d px(layout.pixelX(p.x()), layout.pixelY(p.y()));
    if (pixels.empty() || (px - pixels.back()).norm() >= kMinStepPx) pixels.push_back(px);
  }
  if (!series.positions.empty()) {
    const Eigen::Vector3d& last = series.positions.back();
    pixels.back() = Eigen::Vector2d(layout.pixelX(last.x()), layout.pixelY(last.y()));
  }
  return pixels;
}

std::vector<DrawnSeries> drawnSeries(const PlotSeries& ground_truth,
                                     const std::vector<PlotSeries>& estimates,
                                     const Layout& layout) {
  std::vector<DrawnSeries> drawn;
  drawn.push_back({ground_truth.label, toPixels(ground_truth, layout), kGroundTruthColour, 2.0});
  for (std::size_t k = 0; k < estimates.size(); ++k) {
    drawn.push_back(
        {estimates[k].label, toPixels(estimates[k], layout), kPalette[k % kPalette.size()], 1.5});
  }
  return drawn;
}

// ---- SVG ----

std::string svgText(double x, double y, const std::string& text, const char* anchor, int size = 12,
                    const std::string& extra = {}) {
  return fmt::format(
      "<text x=\"{:.1f}\" y=\"{:.1f}\" font-size=\"{}\" text-anchor=\"{}\"{}>{}</text>\n", x, y,
      size, anchor, extra, escapeXml(text));
}

std::string svgAxes(const Layout& l, const std::string& title) {
  std::string out;
  for (double x : ticks(l.x0, l.x1(), l.tick_step_m)) {
    out += fmt::format(
        "<line x1=\"{0:.1f}\" y1=\"{1:.1f}\" x2=\"{0:.1f}\" y2=\"{2:.1f}\" "
        "stroke=\"{3}\" stroke-width=\"1\"/>\n",
        l.pixelX(x), l.top, l.top + l.area_height, kGridColour.hex());
    out += svgText(l.pixelX(x), l.top + l.area_height + 18, tickLabel(x, l.tick_step_m), "middle");
  }
  for (double y : ticks(l.y0, l.y1(), l.tick_step_m)) {
    out += fmt::format(
        "<line x1=\"{1:.1f}\" y1=\"{0:.1f}\" x2=\"{2:.1f}\" y2=\"{0:.1f}\" "
        "stroke=\"{3}\" stroke-width=\"1\"/>\n",
        l.pixelY(y), l.left, l.left + l.area_width, kGridColour.hex());
    out += svgText(l.left - 8, l.pixelY(y) + 4, tickLabel(y, l.tick_step_m), "end");
  }
  out += fmt::format(
      "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" "
      "fill=\"none\" stroke=\"black\" stroke-width=\"1\"/>\n",
      l.left, l.top, l.area_width, l.area_height);
  out += svgText(l.left + 0.5 * l.area_width, l.height - 18, l.x_axis + " [m]", "middle", 14);
  const double label_y = l.top + 0.5 * l.area_height;
  out += svgText(22, label_y, l.y_axis + " [m]", "middle", 14,
                 fmt::format(" transform=\"rotate(-90 22 {:.1f})\"", label_y));
  out += svgText(0.5 * l.width, 30, title, "middle", 16, " font-weight=\"bold\"");
  return out;
}

std::string svgPolyline(const DrawnSeries& s) {
  std::string points;
  for (const Eigen::Vector2d& p : s.pixels)
    points += fmt::format("{:.1f},{:.1f} ", p.x(), p.y());
  return fmt::format(
      "<polyline points=\"{}\" fill=\"none\" stroke=\"{}\" stroke-width=\"{}\" "
      "stroke-linejoin=\"round\"/>\n",
      points, s.colour.hex(), s.line_width);
}

std::string svgLegend(const std::vector<DrawnSeries>& series, const Layout& l) {
  std::size_t longest = 0;
  for (const DrawnSeries& s : series)
    longest = std::max(longest, s.label.size());
  const double x = l.left + 10, y = l.top + 10;
  const double width = 50.0 + 7.0 * static_cast<double>(longest), height = 20.0 * series.size() + 8;
  std::string out = fmt::format(
      "<rect x=\"{:.1f}\" y=\"{:.1f}\" width=\"{:.1f}\" height=\"{:.1f}\" "
      "fill=\"white\" fill-opacity=\"0.85\" stroke=\"#888888\"/>\n",
      x, y, width, height);
  for (std::size_t k = 0; k < series.size(); ++k) {
    const double row_y = y + 16.0 + 20.0 * static_cast<double>(k);
    out += fmt::format(
        "<line x1=\"{:.1f}\" y1=\"{:.1f}\" x2=\"{:.1f}\" y2=\"{:.1f}\" stroke=\"{}\" "
        "stroke-width=\"{}\"/>\n",
        x + 8, row_y - 4, x + 36, row_y - 4, series[k].colour.hex(), series[k].line_width + 1.0);
    out += svgText(x + 42, row_y, series[k].label, "start");
  }
  return out;
}

void writeSvg(const std::filesystem::path& file, const std::vector<DrawnSeries>& series,
              const Layout& layout, const PlotOptions& options) {
  std::ofstream out(file, std::ios::binary);
  if (!out) throw InputError(InputLocation(file), "cannot open the plot file for writing");
  out << fmt::format(
      "<svg xmlns=\"http://www.w3.org/2000/svg\" width=\"{0}\" height=\"{1}\" "
      "viewBox=\"0 0 {0} {1}\" font-family=\"sans-serif\">\n",
      options.width, options.height);
  out << fmt::format("<rect width=\"{}\" height=\"{}\" fill=\"white\"/>\n", options.width,
                     options.height);
  out << svgAxes(layout, options.title);
  for (const DrawnSeries& s : series)
    out << svgPolyline(s);
  out << svgLegend(series, layout);
  out << "</svg>\n";
  out.close();
  if (!out) throw InputError(InputLocation(file), "failed while writing the plot file");
}

// ---- PNG ----

cv::Point toCv(const Eigen::Vector2d& p) {
  return cv::Point(static_cast<int>(std::lround(p.x())), static_cast<int>(std::lround(p.y())));
}

void cvText(cv::Mat& image, const std::string& text, double x, double y, const char* anchor,
            double font_scale = 0.45) {
  int baseline = 0;
  const cv::Size size = cv::getTextSize(text, cv::FONT_HERSHEY_SIMPLEX, font_scale, 1, &baseline);
  const double shift = std::string(anchor) == "middle" ? 0.5 * size.width
                       : std::string(anchor) == "end"  ? size.width
                                                       : 0.0;
  cv::putText(image, text, toCv({x - shift, y}), cv::FONT_HERSHEY_SIMPLEX, font_scale, kBlack.bgr(),
              1, cv::LINE_AA);
}

void drawCvAxes(cv::Mat& image, const Layout& l, const std::string& title) {
  const int top = static_cast<int>(l.top), bottom = static_cast<int>(l.top + l.area_height);
  const int left = static_cast<int>(l.left), right = static_cast<int>(l.left + l.area_width);
  for (double x : ticks(l.x0, l.x1(), l.tick_step_m)) {
    const int px = static_cast<int>(std::lround(l.pixelX(x)));
    cv::line(image, {px, top}, {px, bottom}, kGridColour.bgr(), 1);
    cvText(image, tickLabel(x, l.tick_step_m), px, bottom + 18, "middle");
  }
  for (double y : ticks(l.y0, l.y1(), l.tick_step_m)) {
    const int py = static_cast<int>(std::lround(l.pixelY(y)));
    cv::line(image, {left, py}, {right, py}, kGridColour.bgr(), 1);
    cvText(image, tickLabel(y, l.tick_step_m), l.left - 8, py + 4, "end");
  }
  cv::rectangle(image, {left, top}, {right, bottom}, kBlack.bgr(), 1);
  cvText(image, l.x_axis + " [m]", l.left + 0.5 * l.area_width, l.height - 18, "middle", 0.55);
  cvText(image, l.y_axis + " [m]", 8, l.top - 10, "start", 0.55);  // Hershey text cannot be rotated
  cvText(image, title, 0.5 * l.width, 30, "middle", 0.65);
}

void drawCvLegend(cv::Mat& image, const std::vector<DrawnSeries>& series, const Layout& l) {
  int text_width = 0;
  for (const DrawnSeries& s : series) {
    int baseline = 0;
    text_width = std::max(
        text_width, cv::getTextSize(s.label, cv::FONT_HERSHEY_SIMPLEX, 0.45, 1, &baseline).width);
  }
  const int x = static_cast<int>(l.left) + 10, y = static_cast<int>(l.top) + 10;
  const int height = 20 * static_cast<int>(series.size()) + 8;
  cv::rectangle(image, {x, y}, {x + 52 + text_width, y + height}, cv::Scalar(255, 255, 255),
                cv::FILLED);
  cv::rectangle(image, {x, y}, {x + 52 + text_width, y + height}, cv::Scalar(136, 136, 136), 1);
  for (std::size_t k = 0; k < series.size(); ++k) {
    const int row_y = y + 16 + 20 * static_cast<int>(k);
    cv::line(image, {x + 8, row_y - 4}, {x + 36, row_y - 4}, series[k].colour.bgr(), 3,
             cv::LINE_AA);
    cvText(image, series[k].label, x + 42, row_y, "start");
  }
}

void writePng(const std::filesystem::path& file, const std::vector<DrawnSeries>& series,
              const Layout& layout, const PlotOptions& options) {
  cv::Mat image(options.height, options.width, CV_8UC3, cv::Scalar(255, 255, 255));
  drawCvAxes(image, layout, options.title);
  for (const DrawnSeries& s : series) {
    if (s.pixels.empty()) continue;
    std::vector<cv::Point> points;
    for (const Eigen::Vector2d& p : s.pixels)
      points.push_back(toCv(p));
    cv::polylines(image, points, false, s.colour.bgr(), static_cast<int>(std::lround(s.line_width)),
                  cv::LINE_AA);
  }
  drawCvLegend(image, series, layout);
  bool written = false;
  try {
    written = cv::imwrite(file.string(), image);
  } catch (const cv::Exception& e) {
    throw InputError(InputLocation(file), fmt::format("cannot write the PNG: {}", e.what()));
  }
  if (!written) throw InputError(InputLocation(file), "cannot write the PNG file");
}

}  // namespace

void PlotOptions::validate() const {
  for (const auto& [name, value] : {std::pair{"width", width}, std::pair{"height", height}}) {
    if (value < kMinImageSize || value > kMaxImageSize) {
      throw OptionError(name, fmt::format("must be between {} and {} pixels, got {}", kMinImageSize,
                                          kMaxImageSize, value));
    }
  }
}

PlotSeries toPlotSeries(const Trajectory& trajectory, const std::string& label) {
  PlotSeries series{label, {}};
  series.positions.reserve(trajectory.size());
  for (const StampedPose& pose : trajectory)
    series.positions.push_back(pose.T_w_x.t);
  return series;
}

PlotSeries alignedEstimateSeries(const EvaluationResult& result, const std::string& label) {
  PlotSeries series{label, {}};
  series.positions.reserve(result.poses.size());
  for (const PoseError& pose : result.poses)
    series.positions.push_back(pose.aligned_position);
  return series;
}

double niceTickStep(double range, int ticks) {
  if (!(range > 0.0) || ticks < 1) return 1.0;
  const double raw = range / ticks;
  const double magnitude = std::pow(10.0, std::floor(std::log10(raw)));
  const double normalised = raw / magnitude;
  if (normalised < 1.5) return magnitude;
  if (normalised < 3.5) return 2.0 * magnitude;
  if (normalised < 7.5) return 5.0 * magnitude;
  return 10.0 * magnitude;
}

std::string escapeXml(const std::string& text) {
  std::string out;
  for (char c : text) {
    switch (c) {
      case '&':
        out += "&amp;";
        break;
      case '<':
        out += "&lt;";
        break;
      case '>':
        out += "&gt;";
        break;
      case '"':
        out += "&quot;";
        break;
      case '\'':
        out += "&apos;";
        break;
      default:
        out += c;
    }
  }
  return out;
}

PlotSpan parsePlotSpan(const std::string& name) {
  if (name == "estimate") return PlotSpan::kEstimate;
  if (name == "all") return PlotSpan::kAll;
  throw OptionError("plot span", fmt::format("'{}' is not estimate or all", name));
}

Trajectory plottedGroundTruth(const Trajectory& gt,
                              const std::vector<const EvaluationResult*>& results, PlotSpan span) {
  if (span == PlotSpan::kAll) return gt;
  std::optional<TimeNs> begin, end;
  for (const EvaluationResult* result : results) {
    if (result->poses.empty()) continue;
    const TimeNs first = result->poses.front().t_ns, last = result->poses.back().t_ns;
    begin = begin ? std::min(*begin, first) : first;
    end = end ? std::max(*end, last) : last;
  }
  if (!begin) return gt;
  Trajectory within;
  for (const StampedPose& pose : gt)
    if (pose.t_ns >= *begin && pose.t_ns <= *end) within.push_back(pose);
  return within;
}

PlotPlane parsePlotPlane(const std::string& name) {
  if (name == "auto") return PlotPlane::kAuto;
  if (name == "xy") return PlotPlane::kXY;
  if (name == "xz") return PlotPlane::kXZ;
  if (name == "yz") return PlotPlane::kYZ;
  throw OptionError("plot plane", fmt::format("'{}' is not auto, xy, xz or yz", name));
}

std::string toString(PlotPlane plane) {
  switch (plane) {
    case PlotPlane::kXY:
      return "x-y";
    case PlotPlane::kXZ:
      return "x-z";
    case PlotPlane::kYZ:
      return "y-z";
    case PlotPlane::kAuto:
      break;
  }
  return "auto";
}

PlotPlane groundPlane(const PlotSeries& series) {
  if (series.positions.empty()) return PlotPlane::kXY;
  Eigen::Vector3d lo = series.positions.front(), hi = lo;
  for (const Eigen::Vector3d& p : series.positions) {
    lo = lo.cwiseMin(p);
    hi = hi.cwiseMax(p);
  }
  const Eigen::Vector3d extent = hi - lo;
  // Leave out the axis of least extent (ties keep z out, then y).
  if (extent.z() <= extent.x() && extent.z() <= extent.y()) return PlotPlane::kXY;
  if (extent.y() <= extent.x()) return PlotPlane::kXZ;
  return PlotPlane::kYZ;
}

void writeTopViewPlot(const std::filesystem::path& file, const PlotSeries& ground_truth,
                      const std::vector<PlotSeries>& estimates, const PlotOptions& options) {
  const ImageFormat format = formatFromExtension(file);
  options.validate();
  const PlotPlane plane =
      options.plane == PlotPlane::kAuto ? groundPlane(ground_truth) : options.plane;
  const PlotSeries gt = projectOnto(ground_truth, plane);
  std::vector<PlotSeries> projected;
  for (const PlotSeries& s : estimates)
    projected.push_back(projectOnto(s, plane));
  std::vector<const PlotSeries*> all{&gt};
  for (const PlotSeries& s : projected)
    all.push_back(&s);
  const bool has_points = std::any_of(all.begin(), all.end(),
                                      [](const PlotSeries* s) { return !s->positions.empty(); });
  if (!has_points) throw InputError(InputLocation(file), "nothing to plot: every series is empty");

  Layout layout = computeLayout(all, options);
  const std::string axes = toString(plane);
  layout.x_axis = axes.substr(0, 1);
  layout.y_axis = axes.substr(2, 1);
  PlotOptions titled = options;
  titled.title = fmt::format("{} ({})", options.title, axes);
  const std::vector<DrawnSeries> series = drawnSeries(gt, projected, layout);
  if (format == ImageFormat::kSvg) {
    writeSvg(file, series, layout, titled);
  } else {
    writePng(file, series, layout, titled);
  }
}

}  // namespace superdyna::eval
