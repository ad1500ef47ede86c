#pragma once
// Fusion of duplicated map points after a new keyframe (the idea of ORB-SLAM's SearchInNeighbors,
// written anew). A new keyframe's points are often the same landmarks as points its neighbours
// already hold (stereo points created again, triangulations of the same corner): without fusion
// they stay separate, each with half the observations, and local BA cannot tie them together.
//
// The targets are the keyframe's best covisible keyframes and their best covisible ones. Each
// point of the new keyframe is projected into every target, and each point of the targets into
// the new keyframe; the keypoints within the search radius (scaled by the octave the point's
// distance predicts), of a compatible octave and semantic class, that reproject within the 2-dof
// chi^2 bound are compared by descriptor. The best one below the distance bound is fused: a
// keypoint that observes another point merges the two (the one with fewer observations goes into
// the other, Map::replaceMapPoint), a free keypoint becomes a new observation. Points are matched
// only from within their viewing limits (map::withinViewingLimits). Each fused point is one map
// update (Map::updateLock()); the pyramid (scale factor, levels) is the map's (map::MapOptions).

#include <vector>

#include "superdyna/map/map.h"
#include "superdyna/optim/reprojection_factor.h"

namespace superdyna::mapping {

struct PointFusionOptions {
  bool enabled = true;
  int neighbours = 10;           ///< Best covisible keyframes of the new one, >= 0.
  int second_neighbours = 5;     ///< ... and of each of them, >= 0.
  double radius_px = 3.0;        ///< Search radius at octave 0 [px], > 0.
  int max_distance = 50;         ///< Hamming distance bound [bits], >= 0.
  double max_l2_distance = 0.9;  ///< Euclidean bound (float descriptors), >= 0.
  double reprojection_chi2 = optim::kChi2Mono95;  ///< Reprojection bound (chi^2, 2 dof), > 0.
  /// A keypoint with a stereo depth also checks the point's disparity against its own, as
  /// ORB-SLAM's Fuse checks the right coordinate (bound: stereo_chi2, 3 dof with the two above).
  bool stereo_check = true;
  double stereo_chi2 = optim::kChi2Stereo95;  ///< > 0.
  bool same_class_only = true;  ///< Fuse only within a semantic class (class_wise_matching).
  double sigma0_px = 1.0;       ///< Keypoint standard deviation at octave 0 [px], > 0.
  /// Throws OptionError naming the first invalid field (prefix "mapping.fusion_").
  void validate() const;
  bool operator==(const PointFusionOptions&) const = default;
};

struct PointFusionResult {
  int merged = 0;  ///< Duplicated points merged into another.
  int added = 0;   ///< New observations of existing points.
};

class PointFuser {
 public:
  /// camera: the left camera of the rig (keyframe keypoints are in it); stereo_baseline_m: the
  /// distance between the rig's two cameras, the baseline of the keypoints' stereo depths (0 =
  /// monocular: no disparity check). Validates the options.
  PointFuser(const PointFusionOptions& options, const optim::ReprojectionCamera& camera,
             double stereo_baseline_m = 0.0);

  /// Fuses the points of `keyframe` with those of its neighbours. Deterministic: targets in
  /// covisibility order, points by id.
  PointFusionResult fuse(map::Map& map, map::KeyFrameId keyframe) const;

 private:
  struct View;
  std::vector<map::KeyFrameId> targets(const map::Map& map, map::KeyFrameId keyframe) const;
  PointFusionResult fuseInto(map::Map& map, map::KeyFrameId target,
                             const std::vector<map::MapPointId>& points) const;
  void fuseOne(map::Map& map, View& view, map::MapPointId point_id,
               PointFusionResult& result) const;
  /// Whether a point projecting to normalised `u` at `depth_m` (camera z) lands on keypoint k
  /// within the chi^2 bound at k's sigma [px], its disparity included when k has a stereo depth.
  bool agrees(const Eigen::Vector2d& u, double depth_m, const map::KeyFrameKeypoint& k,
              double sigma_px) const;

  PointFusionOptions options_;
  optim::ReprojectionCamera camera_;
  double focal_px_;
  double stereo_baseline_m_;
};

}  // namespace superdyna::mapping
