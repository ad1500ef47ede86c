#include "superdyna/tracking/tracker.h"

#include <gtest/gtest.h>

#include <random>

#include "superdyna/sim/sequence_generator.h"
#include "superdyna/tracking/front_end.h"
#include "support/test_support.h"

namespace superdyna::tracking {
namespace {

io::CameraCalibration calibrationOf(const sim::RigOptions& rig, const SE3d& T_b_c) {
  io::CameraCalibration c;
  c.name = "cam";
  c.T_b_c = T_b_c;
  c.width = rig.width;
  c.height = rig.height;
  c.rate_hz = rig.camera_rate_hz;
  c.fx = rig.fx;
  c.fy = rig.fy;
  c.cx = rig.cx;
  c.cy = rig.cy;
  return c;
}

Tracker makeTracker(const TrackerOptions& options = {}) {
  const sim::RigOptions rig;
  return Tracker(options, PyramidInfo{}, mapping::LocalMapperOptions{},
                 calibrationOf(rig, rig.T_b_c0()), calibrationOf(rig, rig.T_b_c1()), std::nullopt);
}

FrontEnd makeFrontEnd(const FrontEndOptions& options = {}) {
  const sim::RigOptions rig;
  return FrontEnd(options, calibrationOf(rig, rig.T_b_c0()), calibrationOf(rig, rig.T_b_c1()));
}

TEST(TrackerOptions, RejectsBadValues) {
  TrackerOptions options;
  options.min_inliers = 2;
  test::expectError<OptionError>([&] { options.validate(); }, {"tracker.min_inliers"});
  options = {};
  options.keyframe_tracked_ratio = 1.5;
  test::expectError<OptionError>([&] { options.validate(); }, {"tracker.keyframe_tracked_ratio"});
  options = {};
  options.projection.radius_px = 0.0;
  test::expectError<OptionError>([&] { makeTracker(options); }, {"radius"});
  FrontEndOptions front_end;
  front_end.features.orb.features = 0;
  test::expectError<OptionError>([&] { makeFrontEnd(front_end); }, {"features"});
}

TEST(Tracker, BlankImagesDoNotInitialiseOrCrash) {
  Tracker tracker = makeTracker();
  FrontEnd front_end = makeFrontEnd();
  const sim::RigOptions rig;
  for (int i = 0; i < 3; ++i) {
    io::FrameBundle frame;
    frame.index = static_cast<std::size_t>(i);
    frame.t_ns = secondsToNs(0.05 * i);
    frame.image0 = cv::Mat::zeros(rig.height, rig.width, CV_8UC1);
    frame.image1 = frame.image0.clone();
    const TrackingResult result = tracker.track(front_end.build(frame));
    EXPECT_EQ(result.state, TrackingState::kLost);
    EXPECT_FALSE(result.keyframe);
    EXPECT_TRUE(result.T_w_b.t.isZero());
  }
}

/// A frame seeing the points `p_w` (world) from body pose T_w_b through the simulated rig: one
/// left keypoint per point at its exact projection, descriptor row k of `descriptors`; with
/// `stereo`, depth and right observation too. `decoys` adds, for the listed points, a second
/// keypoint with the same descriptor at `decoy_pixels`.
Frame syntheticFrame(TimeNs t_ns, const SE3d& T_w_b, const std::vector<Eigen::Vector3d>& p_w,
                     const cv::Mat& descriptors, bool stereo,
                     const std::vector<std::pair<int, Eigen::Vector2d>>& decoys = {}) {
  const sim::RigOptions rig;
  const CameraModel camera = rig.cameraModel();
  const SE3d T_c0_w = (T_w_b * rig.T_b_c0()).inverse();
  const SE3d T_c1_w = (T_w_b * rig.T_b_c1()).inverse();
  Frame frame;
  frame.t_ns = t_ns;
  frame.features.descriptor_type = features::DescriptorType::kFloat;
  frame.features.image_size = {rig.width, rig.height};
  std::vector<cv::Mat> rows;
  const auto add = [&](const Eigen::Vector2d& pixel, int row) {
    features::Keypoint k;
    k.pixel = pixel;
    k.angle = -1.0f;
    frame.features.keypoints.push_back(k);
    rows.push_back(descriptors.row(row));
    frame.normalized.push_back(
        Eigen::Vector2d((pixel.x() - rig.cx) / rig.fx, (pixel.y() - rig.cy) / rig.fy));
  };
  for (std::size_t k = 0; k < p_w.size(); ++k) {
    const Eigen::Vector3d p_c0 = T_c0_w * p_w[k];
    add(*camera.project(p_c0), static_cast<int>(k));
    frame.depth_m.push_back(stereo ? p_c0.z() : -1.0);
    frame.p_c0.push_back(p_c0);
    const Eigen::Vector3d p_c1 = T_c1_w * p_w[k];
    frame.right_normalized.push_back(
        stereo ? std::optional<Eigen::Vector2d>(p_c1.head<2>() / p_c1.z()) : std::nullopt);
  }
  for (const auto& [k, pixel] : decoys) {
    add(pixel, k);
    frame.depth_m.push_back(-1.0);
    frame.p_c0.push_back(Eigen::Vector3d::Zero());
    frame.right_normalized.push_back(std::nullopt);
  }
  cv::vconcat(rows, frame.features.descriptors);
  return frame;
}

TEST(Tracker, SecondSearchFromTheFirstPoseRecoversAmbiguousMatches) {
  // 200 points 3-5 m ahead with random unit descriptors. The second frame moved 0.1 m sideways
  // (about 10-15 px of image motion) but, without a motion model, is predicted where the first
  // was. Every even point has a decoy with its own descriptor at the pixel the prediction puts
  // it at: the ratio test rejects both candidates in the 15 px search, so only the odd points
  // match. Searching again within 3 px of the projections from that first pose separates true
  // keypoints from decoys and recovers the even points.
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> x(-2.0, 2.0), y(-1.2, 1.2), z(3.0, 5.0);
  std::normal_distribution<float> normal;
  const sim::RigOptions rig;
  const SE3d T_w_c0 = rig.T_b_c0();  // body at the world origin
  std::vector<Eigen::Vector3d> p_w;
  cv::Mat descriptors(200, 64, CV_32FC1);
  for (int k = 0; k < 200; ++k) {
    p_w.push_back(T_w_c0 * Eigen::Vector3d(x(rng), y(rng), z(rng)));
    for (int c = 0; c < 64; ++c)
      descriptors.at<float>(k, c) = normal(rng);
    cv::normalize(descriptors.row(k), descriptors.row(k));
  }
  const SE3d T_w_b1;
  const SE3d T_w_b2 = T_w_b1 * SE3d(Eigen::Quaterniond::Identity(),
                                    rig.T_b_c0().rotation() * Eigen::Vector3d(0.1, 0.0, 0.0));
  const Frame first = syntheticFrame(0, T_w_b1, p_w, descriptors, true);
  std::vector<std::pair<int, Eigen::Vector2d>> decoys;
  for (int k = 0; k < 200; k += 2)
    decoys.emplace_back(k, first.features.keypoints[static_cast<std::size_t>(k)].pixel);
  const Frame second = syntheticFrame(secondsToNs(0.05), T_w_b2, p_w, descriptors, false, decoys);

  const auto inliersOfSecond = [&](double refine_radius_px) {
    TrackerOptions options;
    options.refine_radius_px = refine_radius_px;
    Tracker tracker = makeTracker(options);
    EXPECT_EQ(tracker.track(first).state, TrackingState::kInitialized);
    const TrackingResult result = tracker.track(second);
    EXPECT_EQ(result.state, TrackingState::kTracking);
    EXPECT_LT((result.T_w_b.t - T_w_b2.t).norm(), 0.01);
    return result.inliers;
  };
  const int single = inliersOfSecond(0.0);
  EXPECT_GE(single, 90);
  EXPECT_LE(single, 105);
  EXPECT_GE(inliersOfSecond(3.0), 195);
  TrackerOptions bad;
  bad.refine_radius_px = -1.0;
  test::expectError<OptionError>([&] { bad.validate(); }, {"tracker.refine_radius_px"});
}

}  // namespace
}  // namespace superdyna::tracking
