#pragma once
// A trajectory: time-stamped poses T_w_x of some frame x (body/IMU or camera) in a world frame.

#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"

namespace superdyna {

struct StampedPose {
  TimeNs t_ns = 0;
  SE3d T_w_x;  ///< Pose of the tracked frame x in the world frame.
};

using Trajectory = std::vector<StampedPose>;

/// Length of the path through the positions, in metres.
double pathLength(const Trajectory& trajectory);

}  // namespace superdyna
