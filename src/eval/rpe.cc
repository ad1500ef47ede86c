#include "superdyna/eval/rpe.h"

#include <fmt/format.h>

#include <algorithm>
#include <cctype>
#include <cmath>
#include <numbers>

#include "superdyna/core/error.h"

namespace superdyna::eval {
namespace {

constexpr double kDegPerRad = 180.0 / std::numbers::pi;
/// Summing thousands of segment lengths rounds; a pair exactly delta apart must not be missed.
constexpr double kPathToleranceM = 1e-9;

std::string lowercase(std::string text) {
  std::transform(text.begin(), text.end(), text.begin(),
                 [](unsigned char c) { return static_cast<char>(std::tolower(c)); });
  return text;
}

/// cumulative[k] = length of the path through positions 0..k, metres.
std::vector<double> cumulativePathLength(const std::vector<SE3d>& poses) {
  std::vector<double> cumulative(poses.size(), 0.0);
  for (std::size_t k = 1; k < poses.size(); ++k) {
    cumulative[k] = cumulative[k - 1] + (poses[k].t - poses[k - 1].t).norm();
  }
  return cumulative;
}

std::vector<std::pair<std::size_t, std::size_t>> pairsByDistance(const std::vector<SE3d>& gt,
                                                                 double delta_m) {
  const std::vector<double> cumulative = cumulativePathLength(gt);
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  std::size_t j = 0;
  for (std::size_t i = 0; i < gt.size(); ++i) {
    // The path length grows with j, so the first j for i + 1 is never before the one for i.
    j = std::max(j, i + 1);
    while (j < gt.size() && cumulative[j] - cumulative[i] < delta_m - kPathToleranceM)
      ++j;
    if (j == gt.size()) break;
    pairs.emplace_back(i, j);
  }
  return pairs;
}

std::vector<std::pair<std::size_t, std::size_t>> pairsByFrames(std::size_t count,
                                                               std::size_t delta_frames) {
  std::vector<std::pair<std::size_t, std::size_t>> pairs;
  for (std::size_t i = 0; i + delta_frames < count; ++i)
    pairs.emplace_back(i, i + delta_frames);
  return pairs;
}

/// The estimate pose with its position multiplied by `scale` (undoes a monocular scale error).
SE3d scaled(const SE3d& pose, double scale) {
  return SE3d(pose.q, scale * pose.t);
}

}  // namespace

DeltaUnit parseDeltaUnit(const std::string& name) {
  const std::string lower = lowercase(name);
  if (lower == "m" || lower == "meters" || lower == "metres") return DeltaUnit::kMeters;
  if (lower == "frames" || lower == "f") return DeltaUnit::kFrames;
  throw OptionError("delta_unit", fmt::format("unknown unit '{}' (expected m or frames)", name));
}

std::string toString(DeltaUnit unit) {
  return unit == DeltaUnit::kMeters ? "m" : "frames";
}

std::string rpeTransUnit(DeltaUnit unit) {
  return unit == DeltaUnit::kMeters ? "m/m" : "m";
}

std::string rpeRotUnit(DeltaUnit unit) {
  return unit == DeltaUnit::kMeters ? "deg/m" : "deg";
}

void RpeOptions::validate() const {
  if (!std::isfinite(delta) || delta <= 0.0) {
    throw OptionError("delta", fmt::format("must be a finite number > 0, got {}", delta));
  }
  if (unit == DeltaUnit::kFrames && (delta < 1.0 || delta != std::floor(delta))) {
    throw OptionError("delta", fmt::format("must be a whole number of frames >= 1, got {}", delta));
  }
}

std::vector<std::pair<std::size_t, std::size_t>> rpePosePairs(const std::vector<SE3d>& gt,
                                                              const RpeOptions& options) {
  options.validate();
  if (options.unit == DeltaUnit::kFrames) {
    return pairsByFrames(gt.size(), static_cast<std::size_t>(options.delta));
  }
  return pairsByDistance(gt, options.delta);
}

RpeResult computeRpe(const std::vector<SE3d>& gt, const std::vector<SE3d>& est, double est_scale,
                     const RpeOptions& options) {
  if (gt.size() != est.size()) {
    throw InputError(fmt::format("RPE needs associated poses, got {} ground-truth and {} estimated",
                                 gt.size(), est.size()));
  }
  RpeResult rpe;
  rpe.delta = options.delta;
  rpe.unit = options.unit;
  rpe.pairs = rpePosePairs(gt, options);
  if (rpe.pairs.empty()) {
    const double path_m = gt.empty() ? 0.0 : cumulativePathLength(gt).back();
    throw InputError(fmt::format(
        "RPE: no pose pair is {} {} apart (the {} associated ground-truth poses span {} frames "
        "and {:.3f} m of path)",
        options.delta, toString(options.unit), gt.size(), gt.empty() ? 0 : gt.size() - 1, path_m));
  }
  // Metres: normalise by the nominal segment length, as the KITTI devkit does.
  const double normaliser = options.unit == DeltaUnit::kMeters ? options.delta : 1.0;
  for (const auto& [i, j] : rpe.pairs) {
    const SE3d gt_motion = gt[i].inverse() * gt[j];
    const SE3d est_motion = scaled(est[i], est_scale).inverse() * scaled(est[j], est_scale);
    const SE3d error = gt_motion.inverse() * est_motion;
    rpe.trans_errors.push_back(error.t.norm() / normaliser);
    rpe.rot_errors.push_back(rotationAngle(error.rotation()) * kDegPerRad / normaliser);
  }
  rpe.trans = computeStatistics(rpe.trans_errors);
  rpe.rot = computeStatistics(rpe.rot_errors);
  return rpe;
}

}  // namespace superdyna::eval
