#include "superdyna/mapping/map_inertial_alignment.h"

namespace superdyna::mapping {

SE3d transformBodyPose(const Sim3d& S_new_old, const SE3d& T_w_b, const SE3d& T_b_c) {
  return (S_new_old * (T_w_b * T_b_c)) * T_b_c.inverse();
}

}  // namespace superdyna::mapping
