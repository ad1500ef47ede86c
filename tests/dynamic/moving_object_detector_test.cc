#include "superdyna/dynamic/moving_object_detector.h"

#include <gtest/gtest.h>

#include <cmath>
#include <iostream>
#include <random>

#include "superdyna/core/error.h"
#include "superdyna/dynamic/relative_motion.h"

namespace superdyna::dynamic {
namespace {

constexpr double kFocal = 400.0;
constexpr int kWidth = 640, kHeight = 480;

CameraModel camera() {
  return CameraModel(kWidth, kHeight, kFocal, kFocal, 320.0, 240.0);
}

/// A 3D point of the synthetic scene with its own descriptor.
struct ScenePoint {
  Eigen::Vector3d p_w;
  int instance = 0;
  int class_id = features::kClassBackground;
  std::array<std::uint8_t, 32> descriptor{};
};

/// What one frame's feature stage would give: keypoints labelled by instance, undistorted
/// normalised coordinates and stereo points, with 0.3 px image noise and 1 % depth noise.
struct SyntheticFrame {
  TimeNs t_ns = 0;
  features::FeatureSet features;
  std::vector<Eigen::Vector2d> normalized;
  std::vector<Eigen::Vector3d> p_c;
  std::vector<double> depth_m;
  std::vector<std::size_t> point_of_keypoint;  ///< The scene point each keypoint sees.
  bool stereo = true;

  FrameObservations view() const {
    FrameObservations view;
    view.t_ns = t_ns;
    view.features = &features;
    view.normalized = &normalized;
    if (stereo) {
      view.p_c = &p_c;
      view.depth_m = &depth_m;
    }
    return view;
  }
  int count(int instance) const {
    int n = 0;
    for (const auto& k : features.keypoints)
      n += k.instance_id == instance;
    return n;
  }
};

class Scene {
 public:
  explicit Scene(std::uint64_t seed) : rng_(seed) {
    addBox(0, features::kClassBackground, {-10, -3, 6}, {10, 2, 30}, 400);
    addBox(1, features::kClassVehicle, {-3.0, 0.0, 8.0}, {-1.5, 1.2, 10.0}, 40);   // parked car
    addBox(2, features::kClassVehicle, {1.5, 0.0, 9.0}, {3.0, 1.2, 11.0}, 40);     // driving car
    addBox(3, features::kClassPedestrian, {0.0, -0.5, 7.0}, {0.4, 1.2, 7.3}, 20);  // standing
  }

  /// A box of background-class points (no instance label), remembered under `tag`.
  void addUnlabelledBox(int tag, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi) {
    const std::size_t first = points_.size();
    addBox(0, features::kClassBackground, lo, hi, 60);
    for (std::size_t i = first; i < points_.size(); ++i)
      unlabelled_[tag].push_back(i);
  }
  /// From the next frame on, the segmenter labels the unlabelled box `tag` as `instance` of
  /// `class_id` (a false detection when the box stands still, a late one when it moves).
  void labelUnlabelled(int tag, int instance, int class_id) {
    for (const std::size_t i : unlabelled_.at(tag)) {
      points_[i].instance = instance;
      points_[i].class_id = class_id;
    }
  }
  void moveUnlabelled(int tag, const Eigen::Vector3d& delta) {
    for (const std::size_t i : unlabelled_[tag])
      points_[i].p_w += delta;
  }
  /// Keypoints of `frame` on the unlabelled box `tag` (dropped by `report` when given).
  int countUnlabelled(const SyntheticFrame& frame, int tag,
                      const MovingObjectReport* report = nullptr) const {
    int n = 0;
    for (std::size_t k = 0; k < frame.point_of_keypoint.size(); ++k) {
      const auto& box = unlabelled_.at(tag);
      const bool on_box =
          std::find(box.begin(), box.end(), frame.point_of_keypoint[k]) != box.end();
      n += on_box && (!report || report->drop[k]);
    }
    return n;
  }
  int countUnlabelled(const SyntheticFrame& frame, int tag,
                      const MovingObjectReport& report) const {
    return countUnlabelled(frame, tag, &report);
  }

  /// A parked car 2 m in front of the first camera.
  void addNearCar(int instance) {
    addBox(instance, features::kClassVehicle, {0.8, 0.0, 2.0}, {2.0, 1.0, 2.4}, 40);
  }

  /// Moves every point of `instance` by `delta` (world frame).
  void move(int instance, const Eigen::Vector3d& delta) {
    for (ScenePoint& point : points_)
      if (point.instance == instance) point.p_w += delta;
  }
  /// Moves the first `count` points of `instance` by `delta` (world frame).
  void movePoints(int instance, int count, const Eigen::Vector3d& delta) {
    for (ScenePoint& point : points_)
      if (point.instance == instance && count-- > 0) point.p_w += delta;
  }
  /// Keypoints of `instance` are found at `octave` (and located with that octave's noise).
  void setOctave(int instance, int octave) { octave_of_[instance] = octave; }
  /// Three pedestrians' points spread over 1.2 m, 6 m ahead of the first camera (a small group
  /// the segmenter gives one mask).
  void addSmallGroup(int instance) {
    addBox(instance, features::kClassPedestrian, {-1.0, -0.5, 6.0}, {0.2, 0.5, 6.2}, 3);
  }
  /// Swaps the descriptors of the first two points of `instance`: each is matched to the other.
  void swapTwoDescriptors(int instance) {
    std::vector<ScenePoint*> on;
    for (ScenePoint& point : points_)
      if (point.instance == instance) on.push_back(&point);
    std::swap(on.at(0)->descriptor, on.at(1)->descriptor);
  }
  /// New descriptors for every point of `instance` but its first `keep`: the next frame's
  /// keypoints on them match none of the last frame's (as when an object comes out from behind
  /// another).
  void redescribe(int instance, int keep = 0) {
    std::uniform_int_distribution<int> byte(0, 255);
    for (ScenePoint& point : points_) {
      if (point.instance != instance || keep-- > 0) continue;
      for (auto& b : point.descriptor)
        b = static_cast<std::uint8_t>(byte(rng_));
    }
  }
  /// Renames instance ids in the next frames (a network segmenter's ids change frame to frame).
  void relabel(std::map<int, int> ids) { relabel_ = std::move(ids); }

  SyntheticFrame observe(const SE3d& T_w_c, TimeNs t_ns, bool stereo = true) {
    std::normal_distribution<double> pixel_noise(0.0, 0.3), depth_noise(0.0, 0.01);
    SyntheticFrame frame;
    frame.t_ns = t_ns;
    frame.stereo = stereo;
    frame.features.image_size = cv::Size(kWidth, kHeight);
    const SE3d T_c_w = T_w_c.inverse();
    std::vector<int> rows;
    for (std::size_t i = 0; i < points_.size(); ++i) {
      const Eigen::Vector3d p_c = T_c_w * points_[i].p_w;
      if (p_c.z() < 0.5) continue;
      // Coarser octaves locate corners less precisely: noise grows with 1.2^octave.
      const auto coarse = octave_of_.find(points_[i].instance);
      const int octave = coarse == octave_of_.end() ? 0 : coarse->second;
      const double noise_scale = std::pow(1.2, octave);
      const Eigen::Vector2d pixel = kFocal * p_c.head<2>() / p_c.z() +
                                    Eigen::Vector2d(320.0 + noise_scale * pixel_noise(rng_),
                                                    240.0 + noise_scale * pixel_noise(rng_));
      if (pixel.x() < 0 || pixel.y() < 0 || pixel.x() >= kWidth || pixel.y() >= kHeight) continue;
      features::Keypoint keypoint;
      keypoint.pixel = pixel;
      keypoint.class_id = points_[i].class_id;
      keypoint.octave = octave;
      const auto renamed = relabel_.find(points_[i].instance);
      keypoint.instance_id = renamed == relabel_.end() ? points_[i].instance : renamed->second;
      frame.features.keypoints.push_back(keypoint);
      frame.normalized.push_back((pixel - Eigen::Vector2d(320.0, 240.0)) / kFocal);
      const double depth = p_c.z() * (1.0 + depth_noise(rng_));
      frame.depth_m.push_back(depth);
      frame.p_c.push_back(depth * frame.normalized.back().homogeneous());
      rows.push_back(static_cast<int>(i));
      frame.point_of_keypoint.push_back(i);
    }
    frame.features.descriptors = cv::Mat(static_cast<int>(rows.size()), 32, CV_8UC1);
    for (std::size_t r = 0; r < rows.size(); ++r) {
      std::copy(points_[rows[r]].descriptor.begin(), points_[rows[r]].descriptor.end(),
                frame.features.descriptors.ptr<std::uint8_t>(static_cast<int>(r)));
    }
    return frame;
  }

 private:
  void addBox(int instance, int class_id, const Eigen::Vector3d& lo, const Eigen::Vector3d& hi,
              int count) {
    std::uniform_real_distribution<double> unit(0.0, 1.0);
    std::uniform_int_distribution<int> byte(0, 255);
    for (int k = 0; k < count; ++k) {
      ScenePoint point;
      point.p_w = lo + (hi - lo).cwiseProduct(Eigen::Vector3d(unit(rng_), unit(rng_), unit(rng_)));
      point.instance = instance;
      point.class_id = class_id;
      for (auto& b : point.descriptor)
        b = static_cast<std::uint8_t>(byte(rng_));
      points_.push_back(point);
    }
  }

  std::mt19937_64 rng_;
  std::vector<ScenePoint> points_;
  std::map<int, int> relabel_;
  std::map<int, int> octave_of_;
  std::map<int, std::vector<std::size_t>> unlabelled_;
};

/// Camera k: 0.25 m further forward and 0.05 m to the right per frame, turning slowly.
SE3d cameraPose(int k) {
  return SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.01 * k, Eigen::Vector3d::UnitY())),
              Eigen::Vector3d(0.05 * k, 0.0, 0.25 * k));
}

TimeNs frameTime(int k) {
  return 1'000'000'000 + 50'000'000LL * k;
}

SE3d curFromPrev(int k) {
  return cameraPose(k).inverse() * cameraPose(k - 1);
}

MovingObjectOptions geometric() {
  MovingObjectOptions options;
  options.mode = DynamicMode::kSemanticGeometric;
  return options;
}

MovingObjectReport detectAfter(MovingObjectDetector& detector, const SyntheticFrame& previous,
                               const SyntheticFrame& current, const SE3d& T_cur_prev) {
  const FrameObservations previous_view = previous.view();
  return detector.detect(&previous_view, current.view(), T_cur_prev);
}

const ObjectDecision& decisionOf(const MovingObjectReport& report, int instance) {
  for (const ObjectDecision& object : report.objects)
    if (object.instance_id == instance) return object;
  throw std::runtime_error("no decision for instance " + std::to_string(instance));
}

int dropped(const SyntheticFrame& frame, const MovingObjectReport& report, int instance) {
  int n = 0;
  for (std::size_t i = 0; i < frame.features.size(); ++i)
    n += report.drop[i] && frame.features.keypoints[i].instance_id == instance;
  return n;
}

TEST(MovingObjectDetectorTest, DropsOnlyTheObjectThatMoves) {
  Scene scene(1);
  MovingObjectDetector detector(geometric(), camera());
  const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
  const MovingObjectReport first = detector.detect(nullptr, f0.view(), SE3d());
  // Nothing to compare with yet: every object is unverified and, by default, dropped.
  EXPECT_EQ(decisionOf(first, 1).decision, ObjectState::kUnverified);
  EXPECT_EQ(first.dropped, f0.count(1) + f0.count(2) + f0.count(3));

  scene.move(2, Eigen::Vector3d(-0.6, 0.0, 0.0));  // 12 m/s across the view
  const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
  const MovingObjectReport report = detectAfter(detector, f0, f1, curFromPrev(1));
  EXPECT_EQ(decisionOf(report, 1).decision, ObjectState::kStatic);
  EXPECT_EQ(decisionOf(report, 2).decision, ObjectState::kMoving);
  EXPECT_EQ(decisionOf(report, 3).decision, ObjectState::kStatic);
  EXPECT_GE(decisionOf(report, 2).pairs, 30);
  EXPECT_EQ(decisionOf(report, 2).tested, 10);
  EXPECT_GE(decisionOf(report, 2).votes, 9);
  EXPECT_EQ(dropped(f1, report, 1), 0);
  EXPECT_EQ(dropped(f1, report, 2), f1.count(2));
  EXPECT_EQ(dropped(f1, report, 3), 0);
  EXPECT_EQ(report.dropped, f1.count(2));
  // The moving car's pairs name its keypoints in the previous frame (their map points go).
  EXPECT_EQ(static_cast<int>(report.moving_previous_keypoints.size()), decisionOf(report, 2).pairs);
  for (const int i : report.moving_previous_keypoints)
    EXPECT_EQ(f0.features.keypoints[static_cast<std::size_t>(i)].instance_id, 2);
  EXPECT_GT(report.background_pairs, 250);
}

ObjectState stateOfACarDrivingWithTheCamera(double speed_factor, bool stereo) {
  Scene scene(2);
  MovingObjectDetector detector(geometric(), camera());
  const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0), stereo);
  // The car drives along the camera's own translation: every point stays on its epipolar line
  // (the paper's test alone cannot see it).
  scene.move(2, speed_factor * (cameraPose(1).t - cameraPose(0).t));
  const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1), stereo);
  const MovingObjectReport report = detectAfter(detector, f0, f1, curFromPrev(1));
  EXPECT_EQ(decisionOf(report, 1).decision, ObjectState::kStatic);
  return decisionOf(report, 2).decision;
}

TEST(MovingObjectDetectorTest, StereoSeesMotionAlongTheEpipolarLineMonoOnlyAgainstTheFlow) {
  // Driving the other way (3 times as fast as the camera), the car's image moves the way a
  // nearer static point's would: only the stereo reprojection sees it.
  EXPECT_EQ(stateOfACarDrivingWithTheCamera(-3.0, true), ObjectState::kMoving);
  EXPECT_EQ(stateOfACarDrivingWithTheCamera(-3.0, false), ObjectState::kStatic);
  // Overtaking the camera (4 times as fast), its image moves against every static point's flow,
  // beyond the point at infinite depth: the ray test sees it without depth too.
  EXPECT_EQ(stateOfACarDrivingWithTheCamera(4.0, true), ObjectState::kMoving);
  EXPECT_EQ(stateOfACarDrivingWithTheCamera(4.0, false), ObjectState::kMoving);
}

TEST(MovingObjectDetectorTest, HysteresisNeedsTwoFramesToChangeAVerifiedState) {
  Scene scene(3);
  // One-frame baseline: each frame's verdict sees only the last step (with two frames, a stop is
  // seen one frame later).
  MovingObjectOptions options = geometric();
  options.baseline_frames = 1;
  options.clear_static_pairs = 0;  // the plain two-frame rule
  MovingObjectDetector detector(options, camera());
  std::vector<SyntheticFrame> frames{scene.observe(cameraPose(0), frameTime(0))};
  std::vector<MovingObjectReport> reports{detector.detect(nullptr, frames[0].view(), SE3d())};
  for (int k = 1; k <= 6; ++k) {
    if (k <= 2) scene.move(2, Eigen::Vector3d(-0.6, 0.0, 0.0));  // car 2 drives, then stops
    if (k >= 4) scene.move(1, Eigen::Vector3d(0.0, 0.0, 0.5));   // car 1 pulls out
    frames.push_back(scene.observe(cameraPose(k), frameTime(k)));
    reports.push_back(detectAfter(detector, frames[k - 1], frames[k], curFromPrev(k)));
  }
  const auto state = [&](int k, int instance) { return decisionOf(reports[k], instance).decision; };
  EXPECT_EQ(state(2, 2), ObjectState::kMoving);
  EXPECT_EQ(state(3, 2), ObjectState::kMoving);  // first static frame: still moving
  EXPECT_EQ(state(4, 2), ObjectState::kStatic);  // second one clears it
  EXPECT_EQ(state(3, 1), ObjectState::kStatic);
  EXPECT_EQ(state(4, 1), ObjectState::kStatic);  // first moving frame of a static car
  EXPECT_EQ(state(5, 1), ObjectState::kMoving);
  EXPECT_EQ(decisionOf(reports[4], 1).votes, decisionOf(reports[4], 1).tested);
}

/// The state of parked car 1, verified static in frames 1-2, after frames 3 and 4 in which only
/// `pairs` of its keypoints pair with the last frame's and each of those is 30 cm off (as
/// mismatched pairs are).
ObjectState parkedCarAfterTwoFramesOfFewWrongPairs(int pairs) {
  Scene scene(3);
  MovingObjectDetector detector(geometric(), camera());
  std::vector<SyntheticFrame> frames{scene.observe(cameraPose(0), frameTime(0))};
  detector.detect(nullptr, frames[0].view(), SE3d());
  ObjectState state = ObjectState::kUnverified;
  for (int k = 1; k <= 4; ++k) {
    if (k >= 3) {
      scene.redescribe(1, pairs);
      scene.movePoints(1, pairs, Eigen::Vector3d(0.3, 0.0, 0.0));
    }
    frames.push_back(scene.observe(cameraPose(k), frameTime(k)));
    const ObjectDecision car =
        decisionOf(detectAfter(detector, frames[k - 1], frames[k], curFromPrev(k)), 1);
    if (k >= 3) {
      EXPECT_EQ(car.votes, pairs);
    }
    state = car.decision;
  }
  return state;
}

TEST(MovingObjectDetectorTest, OneWrongPairDoesNotSetAVerifiedTrackMoving) {
  EXPECT_EQ(parkedCarAfterTwoFramesOfFewWrongPairs(1), ObjectState::kStatic);
  EXPECT_EQ(parkedCarAfterTwoFramesOfFewWrongPairs(2), ObjectState::kMoving);
}

TEST(MovingObjectDetectorTest, AFrameWithEveryTestedPairWithinItsThresholdClearsAStoppedCar) {
  Scene scene(3);
  MovingObjectOptions options = geometric();
  options.baseline_frames = 1;
  const auto stateAfterStopping = [&](int clear_static_pairs) {
    options.clear_static_pairs = clear_static_pairs;
    MovingObjectDetector detector(options, camera());
    Scene copy = scene;
    std::vector<SyntheticFrame> frames{copy.observe(cameraPose(0), frameTime(0))};
    detector.detect(nullptr, frames[0].view(), SE3d());
    std::vector<ObjectState> states;
    for (int k = 1; k <= 3; ++k) {
      if (k <= 2) copy.move(2, Eigen::Vector3d(-0.6, 0.0, 0.0));  // drives, then stops
      frames.push_back(copy.observe(cameraPose(k), frameTime(k)));
      const MovingObjectReport report =
          detectAfter(detector, frames[k - 1], frames[k], curFromPrev(k));
      states.push_back(decisionOf(report, 2).decision);
      if (k == 3) {
        EXPECT_EQ(decisionOf(report, 2).votes, 0);
      }
    }
    return states;
  };
  // Frame 3 is the first after the stop: all 10 tested pairs are within their thresholds.
  EXPECT_EQ(
      stateAfterStopping(0),
      (std::vector<ObjectState>{ObjectState::kMoving, ObjectState::kMoving, ObjectState::kMoving}));
  EXPECT_EQ(
      stateAfterStopping(3),
      (std::vector<ObjectState>{ObjectState::kMoving, ObjectState::kMoving, ObjectState::kStatic}));
}

/// Frames (of 2..7) in which car 2, driving slowly (`step` m per frame), is called moving.
int slowCarMovingFrames(int baseline_frames, double step) {
  Scene scene(10);
  MovingObjectOptions options = geometric();
  options.baseline_frames = baseline_frames;
  MovingObjectDetector detector(options, camera());
  std::vector<SyntheticFrame> frames{scene.observe(cameraPose(0), frameTime(0))};
  detector.detect(nullptr, frames[0].view(), SE3d());
  int moving = 0;
  for (int k = 1; k <= 7; ++k) {
    scene.move(2, Eigen::Vector3d(-step, 0.0, 0.0));
    frames.push_back(scene.observe(cameraPose(k), frameTime(k)));
    const MovingObjectReport report =
        detectAfter(detector, frames[k - 1], frames[k], curFromPrev(k));
    if (k >= 2) moving += decisionOf(report, 2).decision == ObjectState::kMoving;
  }
  return moving;
}

TEST(MovingObjectDetectorTest, TwoFrameBaselineSeesASlowMover) {
  // 1.5 cm per frame (0.3 m/s) at 10 m: about 0.6 px a frame, within the one-frame noise band;
  // over two frames it stands out.
  const int one = slowCarMovingFrames(1, 0.015), two = slowCarMovingFrames(2, 0.015);
  std::cout << "slow car called moving in " << one << " / " << two
            << " of 6 frames (one- / two-frame baseline)\n";
  EXPECT_LE(one, 1);
  EXPECT_GE(two, 5);
}

TEST(MovingObjectDetectorTest, LongerBaselinesSeeASlowerMover) {
  // 0.8 cm per frame (0.16 m/s): about 0.3 px a frame, 0.6 px over two frames, 1.3 px over four.
  // Four-frame chains reach back to frame 0 from frame 4 on, and the car's static track then
  // needs two moving frames: 3 of frames 2-7 is all a four-frame baseline can give.
  const int two = slowCarMovingFrames(2, 0.008), four = slowCarMovingFrames(4, 0.008);
  std::cout << "slower car called moving in " << two << " / " << four
            << " of 6 frames (two- / four-frame baseline)\n";
  EXPECT_LE(two, 1);
  EXPECT_GE(four, 3);
}

TEST(MovingObjectDetectorTest, AnObjectWithFewChainedPairsIsTestedOnItsOtherPairsToo) {
  Scene scene(10);
  MovingObjectDetector detector(geometric(), camera());
  const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
  detector.detect(nullptr, f0.view(), SE3d());
  // All but one of the parked car's keypoints are new in frame 1: in frame 2 one of its pairs
  // continues a pair of frame 1, the others start there.
  scene.redescribe(1, 1);
  const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
  detectAfter(detector, f0, f1, curFromPrev(1));
  const SyntheticFrame f2 = scene.observe(cameraPose(2), frameTime(2));
  const ObjectDecision car = decisionOf(detectAfter(detector, f1, f2, curFromPrev(2)), 1);
  EXPECT_GT(car.pairs, 20);
  EXPECT_EQ(car.tested, geometric().max_tested_pairs);
  EXPECT_EQ(car.decision, ObjectState::kStatic);
}

TEST(MovingObjectDetectorTest, ObjectsKeepTheirStateWhenTheSegmenterRenumbersThem) {
  Scene scene(4);
  MovingObjectDetector detector(geometric(), camera());
  const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
  detector.detect(nullptr, f0.view(), SE3d());
  scene.move(2, Eigen::Vector3d(-0.6, 0.0, 0.0));
  const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
  detectAfter(detector, f0, f1, curFromPrev(1));
  // Car 2 stops, and the segmenter swaps the two cars' ids: the parked car (now id 2) must stay
  // static and the stopped car (now id 1) is still moving for one frame (hysteresis).
  scene.relabel({{1, 2}, {2, 1}});
  const SyntheticFrame f2 = scene.observe(cameraPose(2), frameTime(2));
  const MovingObjectReport report = detectAfter(detector, f1, f2, curFromPrev(2));
  EXPECT_EQ(decisionOf(report, 2).decision, ObjectState::kStatic);
  EXPECT_EQ(decisionOf(report, 1).decision, ObjectState::kMoving);
  EXPECT_EQ(dropped(f2, report, 2), 0);
}

TEST(MovingObjectDetectorTest, AnObjectWithoutPairsInheritsTheTrackItOverlaps) {
  Scene scene(4);
  MovingObjectDetector detector(geometric(), camera());
  const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
  detector.detect(nullptr, f0.view(), SE3d());
  const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
  const MovingObjectReport r1 = detectAfter(detector, f0, f1, curFromPrev(1));
  ASSERT_EQ(decisionOf(r1, 1).decision, ObjectState::kStatic);
  // The parked car's keypoints are all new, and the segmenter renames it: no pair links it to the
  // last frame, only where its last keypoints land.
  scene.redescribe(1);
  scene.relabel({{1, 7}});
  const SyntheticFrame f2 = scene.observe(cameraPose(2), frameTime(2));
  const MovingObjectReport r2 = detectAfter(detector, f1, f2, curFromPrev(2));
  EXPECT_EQ(decisionOf(r2, 7).pairs, 0);
  EXPECT_EQ(decisionOf(r2, 7).track_id, decisionOf(r1, 1).track_id);
  EXPECT_EQ(decisionOf(r2, 7).decision, ObjectState::kStatic);
  EXPECT_EQ(dropped(f2, r2, 7), 0);
  EXPECT_GT(f2.count(7), 20);
  // Another class nearby does not take it: the standing pedestrian keeps its own track.
  EXPECT_EQ(decisionOf(r2, 3).track_id, decisionOf(r1, 3).track_id);
}

/// The decision on a standing group of three people two of whose pairs are mismatched (their
/// descriptors swapped between the frames), with `max_pedestrian_speed_mps`.
ObjectDecision groupWithTwoMismatches(double max_pedestrian_speed_mps) {
  Scene scene(6);
  scene.addSmallGroup(9);
  MovingObjectOptions options = geometric();
  options.max_pedestrian_speed_mps = max_pedestrian_speed_mps;
  MovingObjectDetector detector(options, camera());
  const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
  detector.detect(nullptr, f0.view(), SE3d());
  scene.swapTwoDescriptors(9);
  const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
  return decisionOf(detectAfter(detector, f0, f1, curFromPrev(1)), 9);
}

TEST(MovingObjectDetectorTest, PairsFasterThanTheClassCanMoveAreMismatchesNotVotes) {
  // Swapped points lie up to 1.2 m apart: such a pair means 10-25 m/s for a pedestrian.
  const ObjectDecision ungated = groupWithTwoMismatches(1000.0);
  EXPECT_EQ(ungated.pairs, 3);
  EXPECT_EQ(ungated.votes, 2);
  EXPECT_EQ(ungated.decision, ObjectState::kMoving);
  const ObjectDecision gated = groupWithTwoMismatches(4.0);
  EXPECT_EQ(gated.pairs, 3);
  EXPECT_EQ(gated.tested, 1);
  EXPECT_EQ(gated.votes, 0);
  EXPECT_EQ(gated.decision, ObjectState::kStatic);
}

TEST(MovingObjectDetectorTest, SameInputSameDecisions) {
  const auto run = [] {
    Scene scene(5);
    MovingObjectDetector detector(geometric(), camera());
    const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
    scene.move(2, Eigen::Vector3d(-0.1, 0.02, 0.0));
    const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
    return detectAfter(detector, f0, f1, curFromPrev(1));
  };
  const MovingObjectReport a = run(), b = run();
  ASSERT_EQ(a.objects.size(), b.objects.size());
  for (std::size_t i = 0; i < a.objects.size(); ++i) {
    EXPECT_EQ(a.objects[i].tested, b.objects[i].tested);
    EXPECT_EQ(a.objects[i].votes, b.objects[i].votes);
    EXPECT_EQ(a.objects[i].max_distance_px, b.objects[i].max_distance_px);
  }
  EXPECT_EQ(a.drop, b.drop);
}

TEST(MovingObjectDetectorTest, SemanticModeDropsEveryMovableObjectUntested) {
  Scene scene(6);
  MovingObjectOptions options;
  options.mode = DynamicMode::kSemantic;
  MovingObjectDetector detector(options, camera());
  const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
  const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
  const MovingObjectReport report = detectAfter(detector, f0, f1, curFromPrev(1));
  EXPECT_EQ(report.dropped, f1.count(1) + f1.count(2) + f1.count(3));
  for (const ObjectDecision& object : report.objects)
    EXPECT_EQ(object.tested, 0);
  options.mode = DynamicMode::kOff;
  MovingObjectDetector off(options, camera());
  const MovingObjectReport none = detectAfter(off, f0, f1, curFromPrev(1));
  EXPECT_EQ(none.dropped, 0);
  EXPECT_TRUE(none.objects.empty());
}

TEST(MovingObjectDetectorTest, AVelocityErrorOfThePredictionDoesNotMoveANearParkedCar) {
  // The prediction's translation is 4 cm off (an IMU velocity error of 0.8 m/s at 20 Hz): a static
  // point z metres away is displaced by about 400 * 0.04 / z px, 2 px at the far background but
  // 8 px on a car 2 m away. Refining the relative pose on the background removes the error.
  for (const bool refine : {false, true}) {
    Scene scene(7);
    scene.addNearCar(4);
    MovingObjectOptions options = geometric();
    options.refine_motion = refine;
    MovingObjectDetector detector(options, camera());
    const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
    const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
    SE3d predicted = curFromPrev(1);
    predicted.t += Eigen::Vector3d(0.04, 0.0, 0.0);
    const MovingObjectReport report = detectAfter(detector, f0, f1, predicted);
    EXPECT_EQ(decisionOf(report, 4).decision, refine ? ObjectState::kStatic : ObjectState::kMoving)
        << (refine ? "refined" : "predicted");
    EXPECT_EQ(decisionOf(report, 1).decision, ObjectState::kStatic);
  }
}

/// Marks most keypoints of `instance` as on its mask border, their stereo points pushed to twice
/// the depth (the background behind the silhouette).
void putOnTheBorder(SyntheticFrame& frame, int instance) {
  for (std::size_t k = 0; k < frame.features.size(); ++k) {
    features::Keypoint& keypoint = frame.features.keypoints[k];
    if (keypoint.instance_id != instance || frame.point_of_keypoint[k] % 10 >= 7) continue;
    keypoint.on_instance_border = true;
    frame.depth_m[k] *= 2.0;
    frame.p_c[k] *= 2.0;
  }
}

TEST(MovingObjectDetectorTest, BorderPairsDoNotMoveAParkedCar) {
  // 70 % of the parked car's keypoints are corners on its silhouette whose stereo depth is the
  // background's: tested, they outvote the inner ones.
  for (const bool skip : {false, true}) {
    Scene scene(11);
    MovingObjectOptions options = geometric();
    options.skip_border_pairs = skip;
    MovingObjectDetector detector(options, camera());
    SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
    scene.move(2, Eigen::Vector3d(-0.6, 0.0, 0.0));  // the driving car, with its border too
    SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
    putOnTheBorder(f0, 2);
    putOnTheBorder(f1, 2);
    putOnTheBorder(f0, 1);
    putOnTheBorder(f1, 1);
    const MovingObjectReport report = detectAfter(detector, f0, f1, curFromPrev(1));
    EXPECT_EQ(decisionOf(report, 1).decision, skip ? ObjectState::kStatic : ObjectState::kMoving)
        << (skip ? "border pairs skipped" : "border pairs tested");
    EXPECT_EQ(decisionOf(report, 2).decision, ObjectState::kMoving);
  }
}

TEST(MovingObjectDetectorTest, TheGeometricTestDropsAnUnlabelledMover) {
  // A shopping cart the segmenter does not know: background class, but it moves.
  for (const bool geometric : {false, true}) {
    Scene scene(9);
    scene.addUnlabelledBox(5, {-1.0, 0.2, 6.0}, {0.2, 1.0, 6.6});
    MovingObjectOptions options;
    options.mode = DynamicMode::kSemanticGeometric;
    options.geometric = geometric;
    MovingObjectDetector detector(options, camera());
    const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
    scene.moveUnlabelled(5, Eigen::Vector3d(0.3, 0.0, 0.0));
    const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
    const MovingObjectReport report = detectAfter(detector, f0, f1, curFromPrev(1));
    const int on_cart = scene.countUnlabelled(f1, 5, report);
    const int cart = scene.countUnlabelled(f1, 5);
    ASSERT_GE(cart, 30);
    if (geometric) {
      EXPECT_GE(on_cart, cart * 3 / 4);
      EXPECT_GE(report.moving_background_cells, 1);
      // Static background is kept: few keypoints beyond the cart's own cells go.
      EXPECT_LE(report.geometric_dropped - on_cart, 25);
    } else {
      EXPECT_EQ(on_cart, 0);
      EXPECT_EQ(report.geometric_dropped, 0);
    }
    EXPECT_EQ(decisionOf(report, 1).decision, ObjectState::kStatic);
  }
}

/// Frame 1 of a scene with an unlabelled box (a building front, or a cart) that the segmenter
/// labels a vehicle (instance 8) from frame 1 on, after moving it by `motion`: the report of
/// frame 1 and the box's keypoints in it and dropped.
struct LateLabel {
  MovingObjectReport report;
  int keypoints = 0;
  int dropped = 0;
};
LateLabel boxLabelledInFrameOne(const Eigen::Vector3d& motion, bool background_pairs) {
  Scene scene(12);
  scene.addUnlabelledBox(5, {-1.0, -1.0, 7.0}, {0.5, 0.5, 7.4});
  MovingObjectOptions options = geometric();
  options.background_pairs_for_new_objects = background_pairs;
  MovingObjectDetector detector(options, camera());
  const SyntheticFrame f0 = scene.observe(cameraPose(0), frameTime(0));
  detector.detect(nullptr, f0.view(), SE3d());
  scene.labelUnlabelled(5, 8, features::kClassVehicle);
  scene.moveUnlabelled(5, motion);
  const SyntheticFrame f1 = scene.observe(cameraPose(1), frameTime(1));
  LateLabel late;
  late.report = detectAfter(detector, f0, f1, curFromPrev(1));
  late.keypoints = f1.count(8);
  late.dropped = dropped(f1, late.report, 8);
  return late;
}

TEST(MovingObjectDetectorTest, AFalseDetectionOnStaticStructureIsVerifiedStaticOnTheBackground) {
  // Labelled in this frame only, the box has no pairs among the last frame's objects: without
  // the background's pairs it is unverified, and all its features go.
  const LateLabel without = boxLabelledInFrameOne(Eigen::Vector3d::Zero(), false);
  ASSERT_GE(without.keypoints, 40);
  EXPECT_EQ(decisionOf(without.report, 8).decision, ObjectState::kUnverified);
  EXPECT_EQ(without.dropped, without.keypoints);
  const LateLabel with = boxLabelledInFrameOne(Eigen::Vector3d::Zero(), true);
  EXPECT_EQ(decisionOf(with.report, 8).decision, ObjectState::kStatic);
  EXPECT_GE(decisionOf(with.report, 8).pairs, 30);
  EXPECT_EQ(with.dropped, 0);
  // The real objects are judged as before.
  EXPECT_EQ(decisionOf(with.report, 1).decision, ObjectState::kStatic);
  EXPECT_EQ(decisionOf(with.report, 1).pairs, decisionOf(without.report, 1).pairs);
}

TEST(MovingObjectDetectorTest, BackgroundPairsCannotSetANewObjectMovingOrCullTheBackground) {
  // A mover the segmenter missed in the last frame (0.4 m across the view in 50 ms): its pairs
  // with the background show the motion, but such pairs may also be background the object now
  // hides. It stays unverified (and dropped, as every unverified object), and the background's
  // map points are not culled.
  const LateLabel late = boxLabelledInFrameOne(Eigen::Vector3d(0.4, 0.0, 0.0), true);
  EXPECT_GE(decisionOf(late.report, 8).tested, 5);
  EXPECT_GE(decisionOf(late.report, 8).votes, 5);
  EXPECT_EQ(decisionOf(late.report, 8).decision, ObjectState::kUnverified);
  EXPECT_EQ(late.dropped, late.keypoints);
  EXPECT_TRUE(late.report.moving_previous_keypoints.empty());
}

TEST(MovingObjectDetectorTest, CoarseOctaveKeypointsAreJudgedInTheirOwnUnits) {
  // The parked car is seen only at octave 6 (1.2^6 = 3x the position noise of level 0), the
  // background at level 0: compared in pixels its residuals exceed a level-0 threshold.
  for (const double scale_factor : {1.0, 1.2}) {
    Scene scene(11);
    scene.setOctave(1, 6);
    MovingObjectOptions options = geometric();
    options.baseline_frames = 1;
    MovingObjectDetector detector(options, camera(), scale_factor);
    std::vector<SyntheticFrame> frames{scene.observe(cameraPose(0), frameTime(0))};
    detector.detect(nullptr, frames[0].view(), SE3d());
    int moving = 0;
    for (int k = 1; k <= 6; ++k) {
      frames.push_back(scene.observe(cameraPose(k), frameTime(k)));
      const MovingObjectReport report =
          detectAfter(detector, frames[k - 1], frames[k], curFromPrev(k));
      moving += decisionOf(report, 1).decision == ObjectState::kMoving;
    }
    if (scale_factor > 1.0) {
      EXPECT_EQ(moving, 0) << "octave-scaled";
    } else {
      EXPECT_GE(moving, 1) << "in pixels";
    }
  }
}

TEST(RelativeMotionTest, RecoversThePoseFromStereoPointsDespiteOutliers) {
  std::mt19937_64 rng(8);
  std::uniform_real_distribution<double> x(-5.0, 5.0), z(4.0, 30.0);
  const SE3d truth = curFromPrev(1);
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> observed;
  for (int i = 0; i < 200; ++i) {
    const Eigen::Vector3d p(x(rng), 0.3 * x(rng), z(rng));
    const Eigen::Vector3d q = truth * p;
    points.push_back(p);
    observed.push_back(q.head<2>() / q.z() +
                       (i % 10 == 0 ? Eigen::Vector2d(0.05, -0.03) : Eigen::Vector2d::Zero()));
  }
  SE3d start = truth;
  start.t += Eigen::Vector3d(0.05, -0.02, 0.08);
  start.q = Eigen::Quaterniond(Eigen::AngleAxisd(0.01, Eigen::Vector3d::UnitZ())) * start.q;
  const SE3d refined = refineRelativePose(points, observed, start, kFocal);
  EXPECT_LT((refined.t - truth.t).norm(), 2e-3);
  EXPECT_LT(refined.q.angularDistance(truth.q), 1e-4);
  // Too few points: the prediction is kept.
  points.resize(10);
  observed.resize(10);
  EXPECT_EQ(refineRelativePose(points, observed, start, kFocal).t, start.t);
}

TEST(MovingObjectDetectorTest, OptionsAreCheckedByName) {
  MovingObjectOptions options;
  options.moving_vote_share = 1.5;
  try {
    options.validate();
    FAIL() << "no error";
  } catch (const OptionError& e) {
    EXPECT_NE(std::string(e.what()).find("dynamic.moving_vote_share"), std::string::npos);
  }
  MovingObjectOptions baseline;
  baseline.baseline_frames = kMaxBaselineFrames;
  EXPECT_NO_THROW(baseline.validate());
  baseline.baseline_frames = kMaxBaselineFrames + 1;
  EXPECT_THROW(baseline.validate(), OptionError);
  baseline.baseline_frames = 0;
  EXPECT_THROW(baseline.validate(), OptionError);
  EXPECT_THROW(parseDynamicMode("semantic+geometric", "--dynamic"), OptionError);
  EXPECT_EQ(parseDynamicMode("semantic-geometric", "--dynamic"), DynamicMode::kSemanticGeometric);
}

}  // namespace
}  // namespace superdyna::dynamic
