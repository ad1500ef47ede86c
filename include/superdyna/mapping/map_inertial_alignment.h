#pragma once
// Inertial initialisation of a monocular map: the keyframe poses of the (arbitrarily scaled and
// oriented) visual map and the IMU samples between them go through the inertial-only MAP
// estimation (imu/inertial_initialization.h); the map is then scaled to metres and rotated so that
// gravity points along -z, and the keyframes get their velocities and the estimated bias.
//
// The similarity acts on the cameras, not the body: the camera-to-body offset is metric while the
// visual map is not, so body poses are recomputed from the transformed camera poses
// (T_w_b' = S (T_w_b T_b_c) T_c_b), which keeps every reprojection unchanged.

#include <optional>
#include <span>

#include "superdyna/core/geometry.h"
#include "superdyna/imu/inertial_initialization.h"
#include "superdyna/io/calibration.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/map/map.h"

namespace superdyna::mapping {

/// The body pose after the similarity S_new_old of the world (applied to the camera at T_b_c).
SE3d transformBodyPose(const Sim3d& S_new_old, const SE3d& T_w_b, const SE3d& T_b_c);

/// Applies S_new_old to every keyframe (camera-centred, see above; velocities are rotated and
/// scaled too) and every map point, and refreshes the points' viewing geometry.
void transformMap(map::Map& map, const Sim3d& S_new_old, const SE3d& T_b_c);

struct MapInertialAlignment {
  Sim3d S_w_v;  ///< Applied similarity: visual (old) map frame -> metric, gravity-aligned world.
  imu::InertialInitResult inertial;
};

/// Estimates scale, gravity, velocities and bias over all keyframes of the map (time order = id
/// order), and applies them to the map. `samples` must be time-ordered and cover the keyframe
/// times. Returns nullopt (map unchanged) with fewer than 3 keyframes, when the samples do not
/// cover them, or when the estimate is unusable (solver failure, non-positive or non-finite scale).
std::optional<MapInertialAlignment> alignMapWithInertial(
    map::Map& map, std::span<const io::ImuSample> samples, const io::ImuCalibration& imu,
    const SE3d& T_b_c, const imu::Bias& initial_bias, const imu::InertialInitOptions& options);

}  // namespace superdyna::mapping
