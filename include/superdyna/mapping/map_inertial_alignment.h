#pragma once
// Similarity changes of a monocular map's world (its scale normalisation after the two-view
// initialisation, the metric gravity-aligned frame of the inertial initialisation) applied to
// body poses outside the map (the map itself moves with map::Map::transformWorld, which uses the
// same convention), e.g. the poses the system already reported.
//
// The similarity acts on the cameras, not the body: the camera-to-body offset is metric while the
// visual map is not, so body poses are recomputed from the transformed camera poses
// (T_w_b' = S (T_w_b T_b_c) T_c_b), which keeps every reprojection unchanged.

#include "superdyna/core/geometry.h"
#include "superdyna/map/map.h"

namespace superdyna::mapping {

/// The body pose after the similarity S_new_old of the world (applied to the camera at T_b_c).
SE3d transformBodyPose(const Sim3d& S_new_old, const SE3d& T_w_b, const SE3d& T_b_c);

}  // namespace superdyna::mapping
