#include "superdyna/mapping/map_inertial_alignment.h"

#include <vector>

namespace superdyna::mapping {

SE3d transformBodyPose(const Sim3d& S_new_old, const SE3d& T_w_b, const SE3d& T_b_c) {
  return (S_new_old * (T_w_b * T_b_c)) * T_b_c.inverse();
}

void transformMap(map::Map& map, const Sim3d& S_new_old, const SE3d& T_b_c) {
  for (const map::KeyFrameId id : map.keyFrameIds()) {
    const auto kf = map.keyFrame(id);
    map.setKeyFramePose(id, transformBodyPose(S_new_old, kf->T_w_b, T_b_c));
    map.setKeyFrameInertialState(id, S_new_old.s * (S_new_old.R * kf->v_w), kf->bg, kf->ba);
  }
  const std::vector<map::MapPointId> points = map.mapPointIds();
  for (const map::MapPointId id : points) {
    if (const auto p = map.mapPointPosition(id)) map.setMapPointPosition(id, S_new_old * *p);
  }
  for (const map::MapPointId id : points)
    map.updateNormalAndDistances(id);
}

}  // namespace superdyna::mapping
