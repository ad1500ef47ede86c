#pragma once
// Local mapping, run sequentially after each new keyframe: local bundle adjustment with Ceres over
// the newest keyframe and its best covisible keyframes (the oldest of the window fixed), removal
// of outlier observations, and culling of recent map points that too few keyframes observe.

#include <Eigen/Core>
#include <map>
#include <optional>
#include <utility>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/geometry.h"
#include "superdyna/map/map.h"
#include "superdyna/mapping/point_triangulator.h"
#include "superdyna/optim/reprojection_factor.h"

namespace superdyna::mapping {

struct LocalMapperOptions {
  int window_keyframes = 8;                  ///< Keyframes optimised together (oldest fixed), >= 2.
  int iterations = 10;                       ///< Levenberg-Marquardt iterations per local BA, >= 1.
  double chi2_outlier = optim::kChi2Mono95;  ///< Observations above are removed after BA.
  int cull_after_keyframes = 3;   ///< Age (in keyframes) at which new points are checked, >= 1.
  int min_observations = 2;       ///< Keyframes a checked point must be seen by, >= 1.
  double min_found_ratio = 0.25;  ///< Matched / visible ratio a checked point needs, [0, 1].
  double sigma0_px = 1.0;         ///< Keypoint standard deviation at octave 0 [px], > 0.
  double scale_factor = 1.2;      ///< Pyramid scale between octaves, > 1.
  /// Triangulate new points between each new keyframe and its neighbours before the BA (the only
  /// source of new points in monocular maps). Its sigma0_px and scale_factor are the ones above.
  bool triangulate = false;
  PointTriangulatorOptions triangulation;
  void validate() const;
};

/// Right-camera observations of one keyframe's keypoints (unrectified stereo), by keypoint index.
using RightObservations = std::vector<std::optional<Eigen::Vector2d>>;

class LocalMapper {
 public:
  /// cameras[0] = left, cameras[1] = right (optional) of the rig.
  LocalMapper(const LocalMapperOptions& options, std::vector<optim::ReprojectionCamera> cameras);

  /// Registers a keyframe's right observations and points it created (for culling).
  void addKeyFrame(map::KeyFrameId id, RightObservations right,
                   const std::vector<map::MapPointId>& new_points);

  /// Local BA around `newest`, outlier removal and point culling. Returns the BA observations.
  int processKeyFrame(map::Map& map, map::KeyFrameId newest);

  /// Forget all state (after a map reset).
  void reset();

  const LocalMapperOptions& options() const { return options_; }

 private:
  std::vector<map::KeyFrameId> localWindow(const map::Map& map, map::KeyFrameId newest) const;
  int bundleAdjust(map::Map& map, const std::vector<map::KeyFrameId>& window);
  void cullRecentPoints(map::Map& map, map::KeyFrameId newest);

  LocalMapperOptions options_;
  std::vector<optim::ReprojectionCamera> cameras_;
  std::map<map::KeyFrameId, RightObservations> right_;
  std::vector<std::pair<map::MapPointId, map::KeyFrameId>> recent_points_;
  std::optional<PointTriangulator> triangulator_;
};

}  // namespace superdyna::mapping
