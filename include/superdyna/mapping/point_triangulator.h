#pragma once
// New map points by triangulation between a new keyframe and its best covisible keyframes (the
// idea of ORB-SLAM's CreateNewMapPoints, written anew). Monocular maps grow only this way; stereo
// maps gain far points the stereo matcher cannot place.
//
// For each neighbour with enough baseline (against its median scene depth), keypoints that observe
// no map point in either keyframe are matched by descriptor under the epipolar constraint: the
// distance of the neighbour keypoint to the epipolar line of the new keypoint (normalised
// coordinates, scaled by the focal length to pixels) must be within the 1-dof chi^2 bound of its
// octave sigma, and it must not lie near the epipole. Each pair is triangulated; a new point must
// have enough parallax, lie in front of both cameras, reproject within the 2-dof chi^2 bound in
// both keyframes and be seen at distances consistent with the two octaves. With same_class_only a
// keypoint is matched only with keypoints of its semantic class (class_id), as in tracking.
// The new points of each pair are added as one map update (Map::updateLock()); a keypoint that
// came to observe a point since the keyframes were read keeps it.

#include <vector>

#include "superdyna/map/map.h"
#include "superdyna/optim/reprojection_factor.h"

namespace superdyna::mapping {

struct PointTriangulatorOptions {
  int neighbours = 10;                     ///< Covisible keyframes paired with the new one, >= 1.
  int max_distance = 50;                   ///< Hamming distance bound of a match [bits], >= 0.
  double max_l2_distance = 0.9;            ///< ... Euclidean bound (float descriptors), >= 0.
  double ratio = 0.8;                      ///< Best / second-best distance on the line, (0, 1].
  double min_baseline_depth_ratio = 0.01;  ///< Baseline / neighbour median depth needed, >= 0.
  double max_cos_parallax = 0.9998;        ///< Rays more parallel than this are skipped, (-1, 1].
  double epipolar_chi2 = 3.841;            ///< Epipolar distance bound (chi^2, 1 dof), > 0.
  double reprojection_chi2 = optim::kChi2Mono95;  ///< Reprojection bound (chi^2, 2 dof), > 0.
  double sigma0_px = 1.0;     ///< Keypoint standard deviation at octave 0 [px], > 0.
  double scale_factor = 1.2;  ///< Pyramid scale between octaves, > 1.
  /// Match only keypoints of one class_id (the System sets it from features.class_wise_matching).
  bool same_class_only = false;
  /// Triangulate only keypoints without a stereo depth in either keyframe (stereo rigs: the far
  /// points stereo cannot measure; the others are the tracker's stereo points or were left out on
  /// purpose). The System sets it in stereo modes.
  bool skip_stereo_keypoints = false;
  /// Throws OptionError naming the first invalid field (prefix "mapping.triangulation_").
  void validate() const;
  bool operator==(const PointTriangulatorOptions&) const = default;
};

class PointTriangulator {
 public:
  /// camera: the left camera of the rig (keyframe keypoints are in it). Validates the options.
  PointTriangulator(const PointTriangulatorOptions& options,
                    const optim::ReprojectionCamera& camera);

  /// Creates the points of `keyframe` against its neighbours; returns their ids (in creation
  /// order). Deterministic: neighbours by covisibility order, keypoints by index.
  std::vector<map::MapPointId> createPoints(map::Map& map, map::KeyFrameId keyframe) const;

 private:
  struct View;
  std::vector<map::MapPointId> triangulatePair(map::Map& map, View& current,
                                               const View& neighbour) const;

  PointTriangulatorOptions options_;
  optim::ReprojectionCamera camera_;
  double focal_px_;
};

}  // namespace superdyna::mapping
