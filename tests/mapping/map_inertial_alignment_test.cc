#include "superdyna/mapping/map_inertial_alignment.h"

#include <gtest/gtest.h>

namespace superdyna::mapping {
namespace {

TEST(MapInertialAlignment, WorldSimilarityKeepsEveryReprojection) {
  // A camera offset from the body, as on a MAV: the similarity must act on the camera.
  const SE3d T_b_c(expSO3(Eigen::Vector3d(0.1, -1.5, 0.2)), Eigen::Vector3d(-0.02, 0.06, 0.01));
  map::MapOptions options;
  options.T_b_c = {T_b_c};
  map::Map map(options);
  map::KeyFrame kf;
  kf.T_w_b = SE3d(expSO3(Eigen::Vector3d(0.3, 0.1, -0.2)), Eigen::Vector3d(1, 2, 3));
  kf.v_w = Eigen::Vector3d(0.5, 0, 0);
  kf.keypoints.resize(1);
  const map::KeyFrameId id = map.addKeyFrame(kf);
  map::MapPoint point;
  point.p_w = Eigen::Vector3d(2, 1, 4);
  const map::MapPointId p = map.addMapPoint(point);
  map.addObservation(p, id, 0);
  const Eigen::Vector3d before = (kf.T_w_b * T_b_c).inverse() * point.p_w;

  Sim3d S;
  S.s = 3.5;
  S.R = expSO3(Eigen::Vector3d(0.2, -0.4, 1.0));
  S.t = Eigen::Vector3d(-1, 0.5, 2);
  map.transformWorld(S);
  const SE3d T_w_b = *map.keyFramePose(id);
  const Eigen::Vector3d after = (T_w_b * T_b_c).inverse() * *map.mapPointPosition(p);
  EXPECT_LT((after - S.s * before).norm(), 1e-9);  // same direction, scaled depth
  EXPECT_LT((T_w_b.rotation() - S.R * kf.T_w_b.rotation()).norm(), 1e-9);
  EXPECT_LT((map.keyFrame(id)->v_w - S.s * (S.R * kf.v_w)).norm(), 1e-9);
  EXPECT_LT((transformBodyPose(S, kf.T_w_b, T_b_c).t - T_w_b.t).norm(), 1e-12);
}

}  // namespace
}  // namespace superdyna::mapping
