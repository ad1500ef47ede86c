// Localisation accuracy of the tracker's projection matches against ground truth, for any feature
// configuration: on a EuRoC-layout sequence with exact ground truth (e.g. `superdyna simulate`),
// every stereo keypoint of frame i (3D from its stereo depth) is moved into frame i + gap with the
// ground-truth relative pose and projected; the projection search of the tracker (radius, L2 /
// Hamming bound, ratio of the config's `projection` section) then picks a keypoint of frame
// i + gap. The distance between that keypoint and the projection is the match's error: small
// errors measure keypoint localisation, large ones wrong matches. Also reported: the distance from
// each projection to the nearest keypoint (repeatability) whatever the descriptors say, overall
// and by the point's image motion between the frames (< 5, 5-15, >= 15 px), and the keypoint lag:
// the least-squares slope of the match errors (< 5 px) onto the image motion, 0 when keypoints
// follow the scene, 1 when they stay where they were in frame i.
//
// With SWEEP, the match statistics are also given for a few other radii, ratios and distance
// bounds (same keypoints).
//
//   build/bin/superdyna_match_accuracy SEQUENCE CONFIG [GAP=1] [STEP=10] [SWEEP]

#include <fmt/format.h>

#include <algorithm>
#include <cstdio>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/features/matcher.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/system/system.h"
#include "superdyna/tracking/front_end.h"

namespace {

using namespace superdyna;

SE3d poseAt(const Trajectory& gt, TimeNs t_ns) {
  const auto it = std::lower_bound(gt.begin(), gt.end(), t_ns,
                                   [](const StampedPose& p, TimeNs t) { return p.t_ns < t; });
  if (it == gt.end()) return gt.back().T_w_x;
  if (it == gt.begin() || it->t_ns == t_ns) return it->T_w_x;
  const auto before = it - 1;
  return (t_ns - before->t_ns < it->t_ns - t_ns) ? before->T_w_x : it->T_w_x;
}

double percentile(std::vector<double> values, double q) {
  if (values.empty()) return 0.0;
  std::sort(values.begin(), values.end());
  return values[static_cast<std::size_t>(q * static_cast<double>(values.size() - 1))];
}

double shareBelow(const std::vector<double>& values, double limit) {
  if (values.empty()) return 0.0;
  const auto n = std::count_if(values.begin(), values.end(), [&](double v) { return v < limit; });
  return 100.0 * static_cast<double>(n) / static_cast<double>(values.size());
}

void report(const std::string& what, const std::vector<double>& errors) {
  // Errors below sqrt(5.991) px pass the pose optimiser's chi2 test at a 1 px sigma.
  const auto inliers =
      std::count_if(errors.begin(), errors.end(), [](double e) { return e < 2.448; });
  std::printf(
      "%-20s n=%7zu inl=%7ld median %.2f p75 %.2f p90 %.2f <1px %.1f%% <2px %.1f%% <3px %.1f%%"
      " >5px %.1f%%\n",
      what.c_str(), errors.size(), static_cast<long>(inliers), percentile(errors, 0.5),
      percentile(errors, 0.75), percentile(errors, 0.9), shareBelow(errors, 1.0),
      shareBelow(errors, 2.0), shareBelow(errors, 3.0), 100.0 - shareBelow(errors, 5.0));
}

/// Least-squares slope of the match errors onto the image motion (file comment).
struct LagFit {
  double numerator = 0.0;
  double denominator = 0.0;

  void add(const Eigen::Vector2d& error, const Eigen::Vector2d& motion) {
    if (!(error.norm() < 5.0)) return;  // wrong matches say nothing about localisation
    numerator -= error.dot(motion);
    denominator += motion.squaredNorm();
  }
  double slope() const { return denominator > 0.0 ? numerator / denominator : 0.0; }
};

}  // namespace

int main(int argc, char** argv) {
  if (argc < 3) {
    std::fprintf(stderr, "usage: %s SEQUENCE CONFIG [GAP=1] [STEP=10] [SWEEP]\n", argv[0]);
    return 2;
  }
  const int gap = argc > 3 ? std::atoi(argv[3]) : 1;
  const int step = argc > 4 ? std::atoi(argv[4]) : 10;
  // Projection search variants: the config's own first.
  std::vector<std::pair<std::string, features::ProjectionMatchOptions>> variants;
  system::SystemOptions loaded = system::loadSystemOptions(argv[2]);
  system::applyClassWiseMatching(loaded);
  variants.emplace_back("matches", loaded.tracker.projection);
  if (argc > 5) {
    for (const double radius : {15.0, 8.0, 5.0}) {
      for (const double ratio : {0.9, 0.8, 0.7}) {
        for (const double l2 : {0.9, 0.7}) {
          features::ProjectionMatchOptions o = loaded.tracker.projection;
          o.radius_px = radius;
          o.ratio = ratio;
          o.max_l2_distance = l2;
          variants.emplace_back(fmt::format("r{} q{} d{}", radius, ratio, l2), o);
        }
      }
    }
  }
  const system::SystemOptions& options = loaded;
  io::DatasetSourceOptions source_options;
  source_options.inertial = false;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, argv[1], source_options);
  const Trajectory gt = source->groundTruth();
  tracking::FrontEnd front_end(options.front_end, source->camera0(), source->camera1());
  const CameraModel camera = source->camera0().cameraModel();
  const SE3d T_b_c = source->camera0().T_b_c;

  std::map<std::size_t, tracking::Frame> frames;  // the ones still needed, by index
  std::vector<std::vector<double>> match_errors(variants.size());
  std::vector<double> nearest_errors;
  std::vector<double> nearest_by_motion[3];  // image motion < 5, 5-15, >= 15 px
  std::size_t predicted_count = 0;
  LagFit lag;
  std::size_t index = 0;
  while (auto bundle = source->next()) {
    const bool is_source = index % static_cast<std::size_t>(step) == 0;
    const bool is_target = index >= static_cast<std::size_t>(gap) && frames.count(index - gap) != 0;
    if (is_source || is_target) frames.emplace(index, front_end.build(*bundle));
    if (is_target) {
      const tracking::Frame& a = frames.at(index - gap);
      const tracking::Frame& b = frames.at(index);
      const SE3d T_cb_ca = (poseAt(gt, b.t_ns) * T_b_c).inverse() * (poseAt(gt, a.t_ns) * T_b_c);
      features::FeatureSet query;
      query.descriptor_type = a.features.descriptor_type;
      query.image_size = a.features.image_size;
      std::vector<Eigen::Vector2d> predicted;
      std::vector<cv::Mat> rows;
      for (std::size_t i = 0; i < a.size(); ++i) {
        if (!a.hasStereo(i)) continue;
        const Eigen::Vector3d p = T_cb_ca * a.p_c0[i];
        if (!(p.z() > 0.05)) continue;
        const auto pixel = camera.project(p);
        if (!pixel || !camera.isInImage(*pixel)) continue;
        predicted.push_back(*pixel);
        query.keypoints.push_back(a.features.keypoints[i]);
        rows.push_back(a.features.descriptors.row(static_cast<int>(i)));
      }
      if (!rows.empty()) {
        cv::vconcat(rows, query.descriptors);
        const features::KeypointGrid grid(b.features.keypoints, b.features.image_size);
        for (std::size_t v = 0; v < variants.size(); ++v) {
          for (const features::Match& m : features::matchByProjection(query, predicted, b.features,
                                                                      grid, variants[v].second)) {
            const auto& pixel = b.features.keypoints[static_cast<std::size_t>(m.train)].pixel;
            const Eigen::Vector2d& target = predicted[static_cast<std::size_t>(m.query)];
            match_errors[v].push_back((pixel - target).norm());
            if (v == 0) {
              lag.add(pixel - target,
                      target - query.keypoints[static_cast<std::size_t>(m.query)].pixel);
            }
          }
        }
        for (std::size_t q = 0; q < predicted.size(); ++q) {
          const Eigen::Vector2d& p = predicted[q];
          double best = 1e9;
          for (const auto& k : b.features.keypoints)
            best = std::min(best, (k.pixel - p).norm());
          nearest_errors.push_back(best);
          const double motion = (p - query.keypoints[q].pixel).norm();
          nearest_by_motion[motion < 5.0 ? 0 : (motion < 15.0 ? 1 : 2)].push_back(best);
        }
        predicted_count += predicted.size();
      }
      frames.erase(index - gap);
    }
    if (!is_source) frames.erase(index);
    ++index;
  }
  std::printf("projected stereo points: %zu\n", predicted_count);
  for (std::size_t v = 0; v < variants.size(); ++v)
    report(variants[v].first, match_errors[v]);
  report("nearest", nearest_errors);
  report("nearest, motion<5px", nearest_by_motion[0]);
  report("nearest, 5-15px", nearest_by_motion[1]);
  report("nearest, >=15px", nearest_by_motion[2]);
  std::printf("keypoint lag behind the image motion (matches < 5 px): %.3f\n", lag.slope());
  return 0;
}
