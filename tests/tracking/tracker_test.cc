#include "superdyna/tracking/tracker.h"

#include <gtest/gtest.h>

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

}  // namespace
}  // namespace superdyna::tracking
