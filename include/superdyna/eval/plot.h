#pragma once
// Top view (the ground plane) of the ground truth and aligned estimates, the figure every SLAM
// paper shows. Written as SVG (vector, for papers) or PNG (OpenCV), chosen by the file extension.
// Axes are in metres with equal aspect, so shapes and drift are not distorted.

#include <Eigen/Core>
#include <filesystem>
#include <string>
#include <vector>

#include "superdyna/core/trajectory.h"
#include "superdyna/eval/evaluate.h"

namespace superdyna::eval {

/// A named polyline of positions in metres (the two axes of the plot's plane are drawn).
struct PlotSeries {
  std::string label;
  std::vector<Eigen::Vector3d> positions;
};

/// The positions of `trajectory`.
PlotSeries toPlotSeries(const Trajectory& trajectory, const std::string& label);
/// The aligned estimate positions of an evaluation (in the ground-truth frame).
PlotSeries alignedEstimateSeries(const EvaluationResult& result, const std::string& label);

/// How much of the ground truth a plot shows: the time span of the evaluated estimates (from their
/// earliest to their latest associated pose, so that a short estimate on a long ground truth is
/// visible), or all of it.
enum class PlotSpan { kEstimate, kAll };
/// "estimate", "all"; OptionError otherwise.
PlotSpan parsePlotSpan(const std::string& name);

/// The ground-truth poses plotted with `results` (evaluations against `gt`): with kEstimate, those
/// from the earliest to the latest associated pose of any result; with kAll (or no associated
/// pose), all of them.
Trajectory plottedGroundTruth(const Trajectory& gt,
                              const std::vector<const EvaluationResult*>& results, PlotSpan span);

/// The plane a top view shows. The ground plane is x-y where z is up (EuRoC, TUM, the
/// simulator) and x-z in a camera frame with y down (KITTI's poses); kAuto takes the two axes
/// along which the ground truth extends furthest, which is the ground plane of any vehicle or
/// walking path (they move far more horizontally than vertically).
enum class PlotPlane { kAuto, kXY, kXZ, kYZ };
/// "auto", "xy", "xz", "yz"; OptionError otherwise.
PlotPlane parsePlotPlane(const std::string& name);
std::string toString(PlotPlane plane);  ///< "x-y", "x-z", "y-z" ("auto" for kAuto).
/// kAuto resolved for `series`: the two axes of largest extent (x-y when it is empty).
PlotPlane groundPlane(const PlotSeries& series);

struct PlotOptions {
  int width = 1000;                    ///< Image width in pixels (SVG: user units), >= 200.
  int height = 800;                    ///< Image height in pixels, >= 200.
  std::string title = "Top view";      ///< The plane is appended: "Top view (x-z)".
  PlotPlane plane = PlotPlane::kAuto;  ///< kAuto: the ground truth's groundPlane().

  /// Throws OptionError for sizes below 200 or above 20000 pixels.
  void validate() const;
};

/// 1, 2 or 5 times a power of ten, so that about `ticks` steps span `range` (1 for an empty
/// range): tick steps people read at a glance.
double niceTickStep(double range, int ticks);
/// Text escaped for XML and HTML (& < > " ').
std::string escapeXml(const std::string& text);

/// Draws the ground truth (dark grey) and every estimate (distinct colours) with a legend and
/// metre ticks. The extension of `file` selects the format: ".svg" or ".png" (case-insensitive);
/// anything else throws OptionError. Throws InputError if there is nothing to draw or the file
/// cannot be written.
void writeTopViewPlot(const std::filesystem::path& file, const PlotSeries& ground_truth,
                      const std::vector<PlotSeries>& estimates, const PlotOptions& options = {});

}  // namespace superdyna::eval
