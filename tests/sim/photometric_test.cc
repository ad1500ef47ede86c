// Photometric challenges of the synthetic renderer: motion blur over a mid-exposure-centred
// interval (camera and agents alike) and the exposure gain schedules of IlluminationSchedule.

#include <gtest/gtest.h>

#include <cmath>
#include <opencv2/core.hpp>
#include <optional>
#include <vector>

#include "superdyna/core/error.h"
#include "superdyna/sim/illumination.h"
#include "superdyna/sim/renderer.h"

namespace superdyna::sim {
namespace {

constexpr double kFx = 460.0;
constexpr double kWallDepthM = 2.0;
constexpr double kSpeedMps = 2.0;
constexpr double kExposureS = 0.02;
/// Image motion of the wall over the exposure: fx * v * exposure / depth = 9.2 px.
constexpr double kBlurLengthPx = kFx * kSpeedMps * kExposureS / kWallDepthM;
constexpr TimeNs kFrameNs = 1'000'000'000;
constexpr std::uint16_t kAgentId = 7;

CameraModel pinholeCamera() {
  return CameraModel(752, 480, kFx, kFx, 371.3, 243.7);
}

/// A 4 m wide texture with a dark left half (40) and a bright right half (220), 1 mm texels,
/// constant along v: a vertical step edge at u = 2 m.
Texture stepEdgeTexture() {
  cv::Mat image(1, 4000, CV_8UC1, cv::Scalar(220));
  image(cv::Rect(0, 0, 2000, 1)).setTo(40);
  return Texture::fromImage(image, 0.001);
}

/// A wall 2 m in front of the camera (camera frame = world frame at identity pose), spanning
/// x in [-2, 2] m (edge at x = 0) and y in [y_top, y_top + height].
Quad wallQuad(double y_top, double height) {
  Quad quad;
  quad.origin = Eigen::Vector3d(-2.0, y_top, kWallDepthM);
  quad.edge_u = Eigen::Vector3d(4.0, 0.0, 0.0);
  quad.edge_v = Eigen::Vector3d(0.0, height, 0.0);
  return quad;
}

/// The upper half of the view is a static wall; the lower half is an agent (the same wall)
/// moving left at kSpeedMps when `agent_moves`, else standing still.
Scene edgeScene(bool agent_moves) {
  Scene scene;
  scene.textures.push_back(stepEdgeTexture());
  SceneObject world;
  world.quads.push_back(wallQuad(-1.5, 1.5));
  scene.objects.push_back(world);
  SceneObject agent;
  agent.instance_id = kAgentId;
  agent.quads.push_back(wallQuad(0.0, 1.5));
  const double speed = agent_moves ? kSpeedMps : 0.0;
  agent.T_w_o = [speed](TimeNs t_ns) -> std::optional<SE3d> {
    return SE3d(Eigen::Quaterniond::Identity(),
                Eigen::Vector3d(-speed * nsToSeconds(t_ns - kFrameNs), 0.0, 0.0));
  };
  agent.is_moving = [speed](TimeNs) { return speed != 0.0; };
  scene.objects.push_back(agent);
  return scene;
}

/// Camera moving right (+x) at `speed`, at the origin at kFrameNs.
std::function<SE3d(TimeNs)> slidingCamera(double speed) {
  return [speed](TimeNs t_ns) {
    return SE3d(Eigen::Quaterniond::Identity(),
                Eigen::Vector3d(speed * nsToSeconds(t_ns - kFrameNs), 0.0, 0.0));
  };
}

/// Where a rising edge profile crosses 10 %, 50 % and 90 % of its dark-to-bright range
/// (linear interpolation between pixels) [px].
struct EdgeCrossings {
  double x10 = 0.0, x50 = 0.0, x90 = 0.0;
  double width() const { return x90 - x10; }
};

EdgeCrossings measureEdge(const cv::Mat& image, int row_begin, int row_end) {
  cv::Mat profile;
  cv::reduce(image.rowRange(row_begin, row_end), profile, 0, cv::REDUCE_AVG, CV_64F);
  const auto* p = profile.ptr<double>(0);
  const double low = 40.0, high = 220.0;
  const auto crossing = [&](double fraction) {
    const double level = low + fraction * (high - low);
    for (int c = 1; c < profile.cols; ++c) {
      if (p[c - 1] < level && p[c] >= level) return c - 1 + (level - p[c - 1]) / (p[c] - p[c - 1]);
    }
    return -1.0;
  };
  return {crossing(0.1), crossing(0.5), crossing(0.9)};
}

RenderOptions blurOptions() {
  RenderOptions options;
  options.background_gray = 128;
  options.exposure_s = kExposureS;
  options.blur_samples = 0;  // automatic
  return options;
}

// A box blur of length L turns a step into a ramp whose 10-90 % width is 0.8 L.
constexpr double kExpectedRampPx = 0.8 * kBlurLengthPx;

TEST(MotionBlurTest, MovingCameraWidensAnEdgeByTheImageMotionAroundItsMidExposurePosition) {
  const Renderer renderer(pinholeCamera());
  const Scene scene = edgeScene(false);
  const auto camera = slidingCamera(kSpeedMps);
  const RenderResult sharp = renderer.render(scene, camera, kFrameNs, RenderOptions{});
  const RenderResult blurred = renderer.render(scene, camera, kFrameNs, blurOptions());
  // Every surface is 2 m away: the image moves by exactly fx v e / z; sub-frames 1 px apart.
  EXPECT_NEAR(blurred.exposure_motion_px, kBlurLengthPx, 1e-6);
  EXPECT_EQ(blurred.blur_samples, 11);
  for (const auto& [rows_begin, rows_end] : {std::pair{40, 200}, std::pair{280, 440}}) {
    const EdgeCrossings before = measureEdge(sharp.image, rows_begin, rows_end);
    const EdgeCrossings after = measureEdge(blurred.image, rows_begin, rows_end);
    std::printf("rows %d-%d: 10-90%% edge width sharp %.2f px, blurred %.2f px (box %.2f px)\n",
                rows_begin, rows_end, before.width(), after.width(), kExpectedRampPx);
    EXPECT_LT(before.width(), 1.5);
    EXPECT_NEAR(after.width(), kExpectedRampPx, 0.5);
    // Mid-exposure timestamps: the blurred edge is centred where the sharp one is.
    EXPECT_NEAR(after.x50, before.x50, 0.25);
  }
  EXPECT_EQ(cv::norm(sharp.instance, blurred.instance, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::norm(sharp.depth, blurred.depth, cv::NORM_INF), 0.0);
}

TEST(MotionBlurTest, MovingAgentBlursWhileTheStaticWorldStaysSharp) {
  const Renderer renderer(pinholeCamera());
  const Scene scene = edgeScene(true);
  const auto camera = slidingCamera(0.0);
  const RenderResult sharp = renderer.render(scene, camera, kFrameNs, RenderOptions{});
  const RenderResult blurred = renderer.render(scene, camera, kFrameNs, blurOptions());
  EXPECT_NEAR(blurred.exposure_motion_px, kBlurLengthPx, 1e-6);
  // The static upper half is unchanged to the last bit.
  EXPECT_EQ(cv::norm(sharp.image.rowRange(0, 240), blurred.image.rowRange(0, 240), cv::NORM_INF),
            0.0);
  const EdgeCrossings before = measureEdge(sharp.image, 280, 440);
  const EdgeCrossings after = measureEdge(blurred.image, 280, 440);
  EXPECT_NEAR(after.width(), kExpectedRampPx, 0.5);
  EXPECT_NEAR(after.x50, before.x50, 0.25);
  // The mask is the agent where it is at mid-exposure, not its smear.
  EXPECT_EQ(cv::norm(sharp.instance, blurred.instance, cv::NORM_INF), 0.0);
  EXPECT_EQ(cv::countNonZero(blurred.instance.rowRange(260, 480) == kAgentId),
            cv::countNonZero(blurred.instance.rowRange(260, 480) != 0));
}

TEST(MotionBlurTest, StaticCameraAndSceneRenderTheSharpImage) {
  const Renderer renderer(pinholeCamera());
  const Scene scene = edgeScene(false);
  const auto camera = slidingCamera(0.0);
  RenderOptions options = blurOptions();
  options.noise_sigma = 2.0;
  options.seed = 9;
  const RenderResult blurred = renderer.render(scene, camera, kFrameNs, options);
  EXPECT_EQ(blurred.exposure_motion_px, 0.0);
  EXPECT_EQ(blurred.blur_samples, 1);
  options.exposure_s = 0.0;
  const RenderResult sharp = renderer.render(scene, camera, kFrameNs, options);
  EXPECT_EQ(cv::norm(sharp.image, blurred.image, cv::NORM_INF), 0.0);
  // A fixed count renders the same sub-frame five times: equal up to float rounding.
  options.exposure_s = kExposureS;
  options.blur_samples = 5;
  const RenderResult five = renderer.render(scene, camera, kFrameNs, options);
  EXPECT_EQ(five.blur_samples, 5);
  EXPECT_LE(cv::norm(sharp.image, five.image, cv::NORM_INF), 1.0);
}

TEST(MotionBlurTest, AutomaticSampleCountFollowsTheStepAndTheCap) {
  const Renderer renderer(pinholeCamera());
  const Scene scene = edgeScene(false);
  const auto camera = slidingCamera(kSpeedMps);
  RenderOptions options = blurOptions();
  options.blur_step_px = 2.0;  // 9.2 px / 2 px -> 5 sub-frames
  EXPECT_EQ(renderer.render(scene, camera, kFrameNs, options).blur_samples, 5);
  options.blur_step_px = 0.5;  // 19 wanted, capped
  options.max_blur_samples = 8;
  EXPECT_EQ(renderer.render(scene, camera, kFrameNs, options).blur_samples, 8);
  options.blur_samples = 3;  // fixed count wins
  EXPECT_EQ(renderer.render(scene, camera, kFrameNs, options).blur_samples, 3);
  options = blurOptions();
  options.blur_samples = -1;
  EXPECT_THROW(renderer.render(scene, camera, kFrameNs, options), OptionError);
  options = blurOptions();
  options.blur_step_px = 0.0;
  EXPECT_THROW(renderer.render(scene, camera, kFrameNs, options), OptionError);
  options = blurOptions();
  options.max_blur_samples = 0;
  EXPECT_THROW(renderer.render(scene, camera, kFrameNs, options), OptionError);
}

// ------------------------------------------------------------------------------------------------
// Illumination

TEST(IlluminationTest, GainRatioOfTwoRenderingsMatchesTheGainsOutsideSaturation) {
  const Renderer renderer(pinholeCamera());
  const Scene scene = edgeScene(false);
  RenderOptions options;
  options.noise_sigma = 2.0;
  options.seed = 4;
  const RenderResult nominal = renderer.render(scene, SE3d(), kFrameNs, options);
  for (const double gain : {0.55, 1.15}) {
    options.gain = gain;
    const RenderResult scaled = renderer.render(scene, SE3d(), kFrameNs, options);
    // The dark half (40 -> 22 or 46) stays far from 0 and 255, where nothing clips.
    const cv::Rect dark(20, 20, 300, 440);
    const double ratio = cv::mean(scaled.image(dark))[0] / cv::mean(nominal.image(dark))[0];
    EXPECT_NEAR(ratio, gain, 0.005) << "gain " << gain;
  }
  // Saturation: at gain 2 the bright half clips to 255 everywhere, the dark half doubles.
  options.gain = 2.0;
  options.noise_sigma = 0.0;
  const RenderResult bright = renderer.render(scene, SE3d(), kFrameNs, options);
  EXPECT_EQ(cv::countNonZero(bright.image(cv::Rect(420, 20, 300, 440)) != 255), 0);
  EXPECT_EQ(cv::countNonZero(bright.image(cv::Rect(20, 20, 300, 440)) != 80), 0);
}

TEST(IlluminationTest, NoEffectGivesExactlyUnitGain) {
  const IlluminationSchedule schedule(IlluminationOptions{}, 3, 0);
  for (const TimeNs t : {TimeNs{0}, TimeNs{123'456'789}, TimeNs{60'000'000'000}}) {
    EXPECT_EQ(schedule.gain(0, t), 1.0);
    EXPECT_EQ(schedule.gain(1, t), 1.0);
  }
}

TEST(IlluminationTest, DriftFollowsTheSinusoid) {
  IlluminationOptions options;
  setIlluminationModes("drift", &options);
  options.drift_amplitude = 0.4;
  options.drift_period_s = 20.0;
  const TimeNs t0 = 7'000'000'000;
  const IlluminationSchedule schedule(options, 1, t0);
  EXPECT_DOUBLE_EQ(schedule.gain(0, t0), 1.0);
  EXPECT_NEAR(schedule.gain(0, t0 + 5'000'000'000), 1.4, 1e-12);
  EXPECT_NEAR(schedule.gain(1, t0 + 15'000'000'000), 0.6, 1e-12);
  EXPECT_NEAR(schedule.gain(0, t0 + 2'500'000'000), 1.0 + 0.4 * std::sqrt(0.5), 1e-12);
}

TEST(IlluminationTest, StepsAreConstantWithinIntervalsAndAlternateBrighterAndDarker) {
  IlluminationOptions options;
  setIlluminationModes("steps", &options);
  options.step_amplitude = 0.6;
  options.step_interval_s = 2.0;
  const IlluminationSchedule schedule(options, 5, 0);
  const double lowest_step = std::sqrt(1.6);  // |log gain| >= 0.5 log(1.6)
  EXPECT_EQ(schedule.gain(0, 1'999'999'999), 1.0);
  for (int interval = 1; interval < 12; ++interval) {
    const TimeNs begin = interval * 2'000'000'000LL;
    const double gain = schedule.gain(0, begin);
    EXPECT_EQ(schedule.gain(0, begin + 1'950'000'000), gain);
    EXPECT_EQ(schedule.gain(1, begin + 700'000'000), gain);  // the two cameras step together
    if (interval % 2 == 1) {
      EXPECT_GE(gain, lowest_step - 1e-12);
      EXPECT_LE(gain, 1.6 + 1e-12);
    } else {
      EXPECT_LE(gain, 1.0 / lowest_step + 1e-12);
      EXPECT_GE(gain, 1.0 / 1.6 - 1e-12);
    }
  }
  // The levels depend on the seed.
  const IlluminationSchedule other(options, 6, 0);
  EXPECT_NE(schedule.gain(0, 2'000'000'000), other.gain(0, 2'000'000'000));
}

TEST(IlluminationTest, FlickerIsIndependentPerFrameAndCameraWithinItsAmplitude) {
  IlluminationOptions options;
  setIlluminationModes("flicker", &options);
  options.flicker_amplitude = 0.1;
  const IlluminationSchedule schedule(options, 2, 0);
  double sum = 0.0, sum_sq = 0.0, min_gain = 2.0, max_gain = 0.0;
  int camera_differs = 0;
  constexpr int kFrames = 2000;
  for (int k = 0; k < kFrames; ++k) {
    const TimeNs t = k * 50'000'000LL;
    const double gain = schedule.gain(0, t);
    EXPECT_EQ(gain, schedule.gain(0, t));  // a pure function of the time
    if (std::abs(gain - schedule.gain(1, t)) > 1e-3) ++camera_differs;
    sum += gain;
    sum_sq += gain * gain;
    min_gain = std::min(min_gain, gain);
    max_gain = std::max(max_gain, gain);
  }
  const double mean = sum / kFrames;
  const double stddev = std::sqrt(sum_sq / kFrames - mean * mean);
  EXPECT_NEAR(mean, 1.0, 0.005);
  EXPECT_NEAR(stddev, 0.1 / std::sqrt(3.0), 0.003);  // uniform in [0.9, 1.1]
  EXPECT_GE(min_gain, 0.9);
  EXPECT_LE(max_gain, 1.1);
  EXPECT_LT(min_gain, 0.905);
  EXPECT_GT(max_gain, 1.095);
  EXPECT_GT(camera_differs, kFrames * 9 / 10);
}

TEST(IlluminationTest, EffectsMultiplyAndTheStereoRatioScalesCam1) {
  IlluminationOptions options;
  setIlluminationModes("all", &options);
  options.stereo_gain_ratio = 1.25;
  options.base_gain = 0.5;
  const IlluminationSchedule schedule(options, 8, 0);
  for (const TimeNs t : {TimeNs{3'000'000'000}, TimeNs{11'050'000'000}}) {
    for (const int camera : {0, 1}) {
      const double expected = 0.5 * schedule.driftFactor(t) * schedule.stepFactor(t) *
                              schedule.flickerFactor(camera, t) * (camera == 1 ? 1.25 : 1.0);
      EXPECT_DOUBLE_EQ(schedule.gain(camera, t), expected);
    }
  }
  EXPECT_EQ(illuminationModes(options), "drift,steps,flicker");
}

TEST(IlluminationTest, ParsesEffectListsAndRejectsBadOptions) {
  IlluminationOptions options;
  setIlluminationModes("steps,flicker", &options);
  EXPECT_FALSE(options.drift);
  EXPECT_TRUE(options.steps);
  EXPECT_TRUE(options.flicker);
  EXPECT_EQ(illuminationModes(options), "steps,flicker");
  setIlluminationModes("none", &options);
  EXPECT_FALSE(options.active());
  EXPECT_EQ(illuminationModes(options), "none");
  EXPECT_THROW(setIlluminationModes("drift,glare", &options), OptionError);
  EXPECT_THROW(setIlluminationModes("", &options), OptionError);
  options = {};
  options.drift_amplitude = 0.95;
  EXPECT_THROW(options.validate(), OptionError);
  options = {};
  options.step_interval_s = 0.0;
  EXPECT_THROW(IlluminationSchedule(options, 1, 0), OptionError);
  options = {};
  options.base_gain = 0.0;
  EXPECT_THROW(options.validate(), OptionError);
  options.base_gain = 0.7;
  EXPECT_TRUE(options.active());
  options = {};
  options.stereo_gain_ratio = 5.0;
  EXPECT_THROW(options.validate(), OptionError);
}

}  // namespace
}  // namespace superdyna::sim
