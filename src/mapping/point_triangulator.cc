#include "superdyna/mapping/point_triangulator.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <limits>

#include "superdyna/core/error.h"
#include "superdyna/features/matcher.h"
#include "superdyna/optim/triangulation.h"

namespace superdyna::mapping {

void PointTriangulatorOptions::validate() const {
  if (neighbours < 1) throw OptionError("mapping.triangulation_neighbours", "must be >= 1");
  if (max_distance < 0) throw OptionError("mapping.triangulation_max_distance", "must be >= 0");
  if (!(max_l2_distance >= 0.0)) {
    throw OptionError("mapping.triangulation_max_l2_distance", "must be >= 0");
  }
  if (!(ratio > 0.0 && ratio <= 1.0)) {
    throw OptionError("mapping.triangulation_ratio", "must be in (0, 1]");
  }
  if (!(min_baseline_depth_ratio >= 0.0)) {
    throw OptionError("mapping.triangulation_min_baseline_depth_ratio", "must be >= 0");
  }
  if (!(max_cos_parallax > -1.0 && max_cos_parallax <= 1.0)) {
    throw OptionError("mapping.triangulation_max_cos_parallax", "must be in (-1, 1]");
  }
  if (!(epipolar_chi2 > 0.0))
    throw OptionError("mapping.triangulation_epipolar_chi2", "must be > 0");
  if (!(reprojection_chi2 > 0.0)) {
    throw OptionError("mapping.triangulation_reprojection_chi2", "must be > 0");
  }
  if (!(sigma0_px > 0.0)) throw OptionError("mapping.sigma0_px", "must be > 0");
  if (!(scale_factor > 1.0)) throw OptionError("mapping.scale_factor", "must be > 1");
}

/// A keyframe as the triangulation needs it: the camera pose and which keypoints are still free.
struct PointTriangulator::View {
  map::KeyFrame keyframe;
  SE3d T_w_c;
  SE3d T_c_w;
  std::vector<bool> free;  ///< Keypoint observes no map point (yet) and is valid().
};

namespace {

/// Nearest and second-nearest candidate by descriptor distance.
struct BestTwo {
  int index = -1;
  double distance = std::numeric_limits<double>::max();
  double second = std::numeric_limits<double>::max();
  void offer(int candidate, double d) {
    if (d < distance) {
      second = distance;
      distance = d;
      index = candidate;
    } else if (d < second) {
      second = d;
    }
  }
};

/// Distance of descriptor row i of `a` and row j of `b` (one type and length, as the map's
/// keyframes all come from one extractor).
double descriptorDistance(const cv::Mat& a, int i, const cv::Mat& b, int j) {
  if (a.type() == CV_8UC1) {
    return features::hammingDistance(a.ptr<std::uint8_t>(i), b.ptr<std::uint8_t>(j), a.cols);
  }
  return features::l2Distance(a.ptr<float>(i), b.ptr<float>(j), a.cols);
}

/// Median depth (camera z) of the keyframe's map points; nullopt when it has none.
std::optional<double> medianSceneDepth(const map::Map& map, const map::KeyFrame& keyframe,
                                       const SE3d& T_c_w) {
  std::vector<double> depths;
  for (const map::MapPointId id : keyframe.map_points) {
    if (id == map::kNoMapPoint) continue;
    if (const auto p = map.mapPointPosition(id)) depths.push_back((T_c_w * *p).z());
  }
  if (depths.empty()) return std::nullopt;
  const auto middle = depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2);
  std::nth_element(depths.begin(), middle, depths.end());
  return *middle;
}

Eigen::Vector3d homogeneous(const Eigen::Vector2d& x) {
  return {x.x(), x.y(), 1.0};
}

/// Keypoint `index` of the keyframe observes no map point (false when the keyframe is gone).
bool keypointFree(const map::Map& map, map::KeyFrameId id, int index) {
  bool free = false;
  map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
    free = kf.map_points[static_cast<std::size_t>(index)] == map::kNoMapPoint;
  });
  return free;
}

/// A triangulated point and the keypoints of the two keyframes that observe it.
struct NewPoint {
  map::MapPoint point;
  int current_index = -1;
  int neighbour_index = -1;
};

/// Adds the points with their two observations as one map update. A keypoint that has come to
/// observe a point since the keyframes were read (the tracker's stereo points of a keyframe
/// inserted meanwhile) keeps it: that new point is skipped.
std::vector<map::MapPointId> addPoints(map::Map& map, map::KeyFrameId current,
                                       map::KeyFrameId neighbour, std::vector<NewPoint> points) {
  const map::Map::UpdateLock update = map.updateLock();
  std::vector<map::MapPointId> created;
  for (NewPoint& p : points) {
    if (!keypointFree(map, current, p.current_index) ||
        !keypointFree(map, neighbour, p.neighbour_index)) {
      continue;
    }
    const map::MapPointId id = map.addMapPoint(std::move(p.point));
    map.addObservation(id, current, p.current_index);
    map.addObservation(id, neighbour, p.neighbour_index);
    map.updateNormalAndDistances(id);
    created.push_back(id);
  }
  return created;
}

}  // namespace

PointTriangulator::PointTriangulator(const PointTriangulatorOptions& options,
                                     const optim::ReprojectionCamera& camera)
    : options_(options), camera_(camera), focal_px_(0.5 * (camera.fx + camera.fy)) {
  options_.validate();
  camera_.validate();
}

std::vector<map::MapPointId> PointTriangulator::createPoints(map::Map& map,
                                                             map::KeyFrameId keyframe) const {
  const auto viewOf = [&](map::KeyFrameId id) {
    View view;
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) { view.keyframe = kf; });
    view.T_w_c = view.keyframe.T_w_b * camera_.T_b_c;
    view.T_c_w = view.T_w_c.inverse();
    view.free.resize(view.keyframe.size());
    for (std::size_t i = 0; i < view.keyframe.size(); ++i) {
      // A keypoint whose undistortion failed has no ray to triangulate.
      const map::KeyFrameKeypoint& k = view.keyframe.keypoints[i];
      view.free[i] = view.keyframe.map_points[i] == map::kNoMapPoint && k.valid() &&
                     !(options_.skip_stereo_keypoints && k.hasStereo());
    }
    return view;
  };
  if (!map.hasKeyFrame(keyframe)) return {};
  View current = viewOf(keyframe);
  std::vector<map::MapPointId> created;
  for (const map::KeyFrameId id : map.bestCovisibleKeyFrames(keyframe, options_.neighbours)) {
    const View neighbour = viewOf(id);
    const double baseline = (current.T_w_c.t - neighbour.T_w_c.t).norm();
    const auto depth = medianSceneDepth(map, neighbour.keyframe, neighbour.T_c_w);
    if (!depth || baseline < options_.min_baseline_depth_ratio * *depth) continue;
    for (const map::MapPointId p : triangulatePair(map, current, neighbour))
      created.push_back(p);
  }
  return created;
}

std::vector<map::MapPointId> PointTriangulator::triangulatePair(map::Map& map, View& current,
                                                                const View& neighbour) const {
  // Essential matrix of the pair in normalised coordinates: x_n^T E x_c = 0.
  const SE3d T_n_c = neighbour.T_c_w * current.T_w_c;
  const Eigen::Matrix3d E = hat(T_n_c.t) * T_n_c.rotation();
  // The current camera centre seen from the neighbour (its epipole); matches near it are unstable.
  const Eigen::Vector3d epipole_n = T_n_c.t;
  const bool epipole_visible = epipole_n.z() > 0.0;
  const Eigen::Vector2d epipole = epipole_n.head<2>() / (epipole_visible ? epipole_n.z() : 1.0);
  const auto sigmaOf = [&](int octave) {
    return optim::octaveSigmaPx(octave, options_.sigma0_px, options_.scale_factor);
  };

  const map::KeyFrame& kc = current.keyframe;
  const map::KeyFrame& kn = neighbour.keyframe;
  // best[j]: the current keypoint matched to neighbour keypoint j (each used at most once).
  std::vector<std::pair<int, double>> best_for_neighbour(kn.size(),
                                                         {-1, std::numeric_limits<double>::max()});
  // Binary descriptors (ORB): Hamming distance [bits]; float ones (learned): Euclidean.
  const bool binary = kc.descriptors.type() == CV_8UC1;
  const double max_distance = binary ? options_.max_distance : options_.max_l2_distance;
  for (std::size_t i = 0; i < kc.size(); ++i) {
    if (!current.free[i]) continue;
    const Eigen::Vector3d line = E * homogeneous(kc.keypoints[i].normalized);
    const double line_norm = line.head<2>().norm();
    if (!(line_norm > 0.0)) continue;
    BestTwo best;
    const int row_c = static_cast<int>(i);
    const int class_id = kc.keypoints[i].class_id;
    for (std::size_t j = 0; j < kn.size(); ++j) {
      if (!neighbour.free[j]) continue;
      const map::KeyFrameKeypoint& k = kn.keypoints[j];
      if (options_.same_class_only && k.class_id != class_id) continue;
      const double sigma = sigmaOf(k.octave);
      const double distance_px =
          focal_px_ * std::abs(line.dot(homogeneous(k.normalized))) / line_norm;
      if (distance_px * distance_px > options_.epipolar_chi2 * sigma * sigma) continue;
      if (epipole_visible && focal_px_ * (k.normalized - epipole).norm() <
                                 10.0 * std::pow(options_.scale_factor, k.octave)) {
        continue;
      }
      best.offer(static_cast<int>(j),
                 descriptorDistance(kc.descriptors, row_c, kn.descriptors, static_cast<int>(j)));
    }
    if (best.index < 0 || best.distance > max_distance) continue;
    if (best.second != std::numeric_limits<double>::max() &&
        best.distance >= options_.ratio * best.second) {
      continue;
    }
    auto& slot = best_for_neighbour[static_cast<std::size_t>(best.index)];
    if (best.distance < slot.second) slot = {static_cast<int>(i), best.distance};
  }

  optim::TriangulationOptions triangulation;
  triangulation.max_cos_parallax = options_.max_cos_parallax;
  const double ratio_factor = 1.5 * options_.scale_factor;
  std::vector<NewPoint> triangulated;
  for (std::size_t j = 0; j < kn.size(); ++j) {
    const int i = best_for_neighbour[j].first;
    if (i < 0) continue;
    const map::KeyFrameKeypoint& a = kc.keypoints[static_cast<std::size_t>(i)];
    const map::KeyFrameKeypoint& b = kn.keypoints[j];
    const optim::TriangulationResult r =
        optim::triangulateTwoView(homogeneous(a.normalized), current.T_w_c,
                                  homogeneous(b.normalized), neighbour.T_w_c, triangulation);
    if (!r.ok()) continue;
    const auto reprojects = [&](const View& view, const map::KeyFrameKeypoint& k) {
      const Eigen::Vector3d p_c = view.T_c_w * r.p_w;
      if (!(p_c.z() > 0.0)) return false;
      const double sigma = sigmaOf(k.octave);
      const Eigen::Vector2d error = focal_px_ * (p_c.head<2>() / p_c.z() - k.normalized);
      return error.squaredNorm() <= options_.reprojection_chi2 * sigma * sigma;
    };
    if (!reprojects(current, a) || !reprojects(neighbour, b)) continue;
    // Scale consistency: the distance ratio must agree with the octave ratio.
    const double distance_c = (r.p_w - current.T_w_c.t).norm();
    const double distance_n = (r.p_w - neighbour.T_w_c.t).norm();
    if (!(distance_c > 0.0 && distance_n > 0.0)) continue;
    const double ratio_distance = distance_c / distance_n;
    const double ratio_octave = std::pow(options_.scale_factor, a.octave - b.octave);
    if (ratio_distance * ratio_factor < ratio_octave ||
        ratio_distance > ratio_octave * ratio_factor) {
      continue;
    }
    NewPoint& p = triangulated.emplace_back();
    p.point.p_w = r.p_w;
    p.point.descriptor = kc.descriptors.row(i).clone();
    p.point.class_id = a.class_id;
    p.point.instance_id = a.instance_id;
    p.current_index = i;
    p.neighbour_index = static_cast<int>(j);
    current.free[static_cast<std::size_t>(i)] = false;
  }
  return addPoints(map, kc.id, kn.id, std::move(triangulated));
}

}  // namespace superdyna::mapping
