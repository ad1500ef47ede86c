// The simulated segmenter errors: the asked rates over many frames, false objects only on the
// backend's background, persistence along the image motion, determinism, stereo consistency.

#include "superdyna/semantics/segmenter_errors.h"

#include <gtest/gtest.h>

#include <cstdint>
#include <map>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>
#include <set>
#include <string>
#include <utility>
#include <vector>

#include "superdyna/core/error.h"

namespace superdyna::semantics {
namespace {

constexpr TimeNs kFramePeriodNs = 50'000'000;  // 20 Hz
constexpr int kRealInstances = 4;

/// A backend returning the same four instances in every image (or the ids it is given).
class FixedSegmenter : public Segmenter {
 public:
  explicit FixedSegmenter(bool ids_name_objects, cv::Mat ids = {})
      : ids_name_objects_(ids_name_objects), ids_(std::move(ids)) {}
  Segmentation segment(const cv::Mat& image, TimeNs /*t_ns*/, int /*camera*/) override {
    Segmentation segmentation;
    segmentation.ids = ids_.empty() ? fourInstances(image.size()) : ids_;
    std::set<int> ids;
    for (int r = 0; r < segmentation.ids.rows; ++r)
      for (int c = 0; c < segmentation.ids.cols; ++c)
        if (const int id = segmentation.ids.at<std::uint16_t>(r, c); id != 0) ids.insert(id);
    for (const int id : ids) {
      Instance instance;
      instance.id = id;
      instance.class_id =
          id % 2 == 1 ? sensors::kInstanceClassVehicle : sensors::kInstanceClassPedestrian;
      instance.score = 0.8f;
      segmentation.instances.push_back(instance);
    }
    updateBoxesAndAreas(segmentation);
    return segmentation;
  }
  std::string description() const override { return "fixed"; }
  bool idsNameObjects() const override { return ids_name_objects_; }

  /// Instances 1..4: two vehicles and two pedestrians, ~14 % of a 640x480 image.
  static cv::Mat fourInstances(const cv::Size& size) {
    cv::Mat ids(size, CV_16UC1, cv::Scalar(0));
    ids(cv::Rect(40, 300, 160, 90)).setTo(1);
    ids(cv::Rect(300, 120, 40, 110)).setTo(2);
    ids(cv::Rect(420, 320, 180, 100)).setTo(3);
    ids(cv::Rect(520, 60, 50, 120)).setTo(4);
    return ids;
  }

 private:
  bool ids_name_objects_;
  cv::Mat ids_;
};

/// A blurred noise texture, larger than the images cut from it.
cv::Mat texture() {
  cv::Mat noise(700, 900, CV_8UC1);
  cv::RNG rng(12345);
  rng.fill(noise, cv::RNG::UNIFORM, 0, 256);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 2.0);
  cv::normalize(noise, noise, 0, 255, cv::NORM_MINMAX);
  return noise;
}

/// Frame k of a camera panning over the texture: its content moves by (3, 2) px per frame.
cv::Mat frame(const cv::Mat& texture, int k) {
  return texture(cv::Rect(150 - 3 * k, 100 - 2 * k, 640, 480)).clone();
}

TimeNs timeOf(int k) {
  return 1'000'000'000 + k * kFramePeriodNs;
}

std::unique_ptr<ErrorInjectingSegmenter> wrapped(const SegmenterErrorOptions& options,
                                                 bool ids_name_objects = true) {
  return std::make_unique<ErrorInjectingSegmenter>(
      std::make_unique<FixedSegmenter>(ids_name_objects), options);
}

int countInjected(const Segmentation& segmentation) {
  int n = 0;
  for (const Instance& instance : segmentation.instances)
    n += instance.id >= kInjectedObjectIdBase ? 1 : 0;
  return n;
}

int countReal(const Segmentation& segmentation) {
  return static_cast<int>(segmentation.instances.size()) - countInjected(segmentation);
}

TEST(SegmenterErrors, RatesOverTwoHundredFramesAreTheAskedOnes) {
  SegmenterErrorOptions options;
  options.false_objects_per_frame = 1.0;
  options.miss_rate = 0.1;
  options.seed = 3;
  const auto segmenter = wrapped(options);
  const cv::Mat tex = texture();
  int injected = 0, missed = 0;
  const int frames = 200;
  for (int k = 0; k < frames; ++k) {
    const Segmentation s = segmenter->segment(frame(tex, k % 30), timeOf(k), 0);
    injected += countInjected(s);
    missed += kRealInstances - countReal(s);
  }
  const double mean_injected = static_cast<double>(injected) / frames;
  const double miss_share = static_cast<double>(missed) / (kRealInstances * frames);
  EXPECT_NEAR(mean_injected, 1.0, 0.2) << injected;
  EXPECT_NEAR(miss_share, 0.1, 0.03) << missed;
}

TEST(SegmenterErrors, PersistentFalseObjectsKeepTheAskedMeanAndLifetime) {
  SegmenterErrorOptions options;
  options.false_objects_per_frame = 2.0;
  options.false_object_frames = 5;
  options.seed = 11;
  const auto segmenter = wrapped(options);
  const cv::Mat tex = texture();
  std::map<int, int> run_of_id;  // consecutive frames the living object with this id has lived
  std::vector<int> lives;        // of the objects that vanished
  int injected = 0;
  const int frames = 400;
  for (int k = 0; k < frames; ++k) {
    // Back and forth over the texture, so the objects can always be followed.
    const int position = (k / 30) % 2 == 0 ? k % 30 : 29 - k % 30;
    const Segmentation s = segmenter->segment(frame(tex, position), timeOf(k), 0);
    injected += countInjected(s);
    std::map<int, int> now;
    for (const FalseObject& object : segmenter->falseObjects())
      now[object.id] = run_of_id.contains(object.id) ? run_of_id[object.id] + 1 : 1;
    for (const auto& [id, lived] : run_of_id)
      if (!now.contains(id)) lives.push_back(lived);
    run_of_id = std::move(now);
  }
  EXPECT_NEAR(static_cast<double>(injected) / frames, 2.0, 0.4) << injected;
  ASSERT_GT(lives.size(), 100u);
  int full_lives = 0;
  for (const int lived : lives) {
    EXPECT_LE(lived, 5);
    full_lives += lived == 5 ? 1 : 0;
  }
  // The first frame's objects have less left to live; most others live their 5 frames.
  EXPECT_GT(full_lives, static_cast<int>(lives.size()) * 3 / 4) << full_lives;
}

TEST(SegmenterErrors, FalseObjectsLieOnlyOnTheBackendsBackground) {
  SegmenterErrorOptions options;
  options.false_objects_per_frame = 4.0;
  options.false_object_min_px = 60;
  options.false_object_max_px = 240;  // large: they would overlap the real ones if allowed
  options.miss_rate = 0.3;
  const auto segmenter = wrapped(options);
  const cv::Mat tex = texture();
  const cv::Mat real = FixedSegmenter::fourInstances({640, 480});
  int injected_pixels = 0;
  for (int k = 0; k < 50; ++k) {
    const Segmentation s = segmenter->segment(frame(tex, k % 30), timeOf(k), 0);
    const cv::Mat injected = s.ids >= kInjectedObjectIdBase;
    injected_pixels += cv::countNonZero(injected);
    EXPECT_EQ(cv::countNonZero(injected & (real != 0)), 0) << k;  // not even on missed ones
    for (const Instance& instance : s.instances) {
      EXPECT_EQ(cv::countNonZero(s.ids == instance.id), instance.area_px) << instance.id;
      if (instance.id < kInjectedObjectIdBase) continue;
      EXPECT_LE(instance.id, kInjectedObjectIdLast);
      EXPECT_TRUE(instance.class_id == sensors::kInstanceClassVehicle ||
                  instance.class_id == sensors::kInstanceClassPedestrian);
      EXPECT_FLOAT_EQ(instance.score, 0.8f);  // the real instances' median: indistinguishable
      EXPECT_LE(std::max(instance.box.width, instance.box.height), 241);
    }
  }
  EXPECT_GT(injected_pixels, 50 * 4 * 1000);  // they are there, and not tiny
}

TEST(SegmenterErrors, FalseObjectsFollowTheStructureUnderThem) {
  SegmenterErrorOptions options;
  options.false_objects_per_frame = 3.0;
  options.false_object_frames = 6;
  options.seed = 5;
  const auto segmenter = wrapped(options);
  const cv::Mat tex = texture();
  std::map<int, cv::Point2d> before;
  int followed = 0;
  for (int k = 0; k < 30; ++k) {
    segmenter->segment(frame(tex, k), timeOf(k), 0);
    std::map<int, cv::Point2d> now;
    for (const FalseObject& object : segmenter->falseObjects()) {
      now[object.id] = object.centre;
      if (!before.contains(object.id)) continue;
      // Near the right or bottom border the structure leaves the image: not followed there.
      if (before[object.id].x > 640 - 40 || before[object.id].y > 480 - 40) continue;
      // The content moves by (+3, +2) px per frame: so does the object.
      EXPECT_NEAR(object.centre.x - before[object.id].x, 3.0, 1e-9) << object.id;
      EXPECT_NEAR(object.centre.y - before[object.id].y, 2.0, 1e-9) << object.id;
      ++followed;
    }
    before = now;
  }
  EXPECT_GT(followed, 50);
}

TEST(SegmenterErrors, SameSeedAndTimesGiveIdenticalMasksAnotherSeedOthers) {
  SegmenterErrorOptions options;
  options.false_objects_per_frame = 1.5;
  options.false_object_frames = 3;
  options.miss_rate = 0.2;
  options.seed = 42;
  const cv::Mat tex = texture();
  const auto a = wrapped(options);
  const auto b = wrapped(options);
  options.seed = 43;
  const auto c = wrapped(options);
  int frames_differing = 0;
  for (int k = 0; k < 20; ++k) {
    const Segmentation sa = a->segment(frame(tex, k), timeOf(k), 0);
    const Segmentation sb = b->segment(frame(tex, k), timeOf(k), 0);
    const Segmentation sc = c->segment(frame(tex, k), timeOf(k), 0);
    EXPECT_EQ(cv::countNonZero(sa.ids != sb.ids), 0) << k;
    EXPECT_EQ(sa.instances, sb.instances) << k;
    frames_differing += cv::countNonZero(sa.ids != sc.ids) > 0 ? 1 : 0;
  }
  EXPECT_GE(frames_differing, 15);
}

TEST(SegmenterErrors, WithoutPersistenceAFrameDependsOnlyOnSeedAndTime) {
  SegmenterErrorOptions options;
  options.false_objects_per_frame = 2.0;
  options.miss_rate = 0.25;
  options.seed = 9;
  const cv::Mat tex = texture();
  const auto sequence = wrapped(options);
  Segmentation tenth;
  for (int k = 0; k <= 10; ++k)
    tenth = sequence->segment(frame(tex, k), timeOf(k), 0);
  const Segmentation alone = wrapped(options)->segment(frame(tex, 10), timeOf(10), 0);
  EXPECT_EQ(cv::countNonZero(alone.ids != tenth.ids), 0);
  EXPECT_EQ(alone.instances, tenth.instances);
}

TEST(SegmenterErrors, TheRightImageGetsTheLeftImagesErrors) {
  SegmenterErrorOptions options;
  options.false_objects_per_frame = 2.0;
  options.miss_rate = 0.3;
  const auto segmenter = wrapped(options, /*ids_name_objects=*/true);
  const cv::Mat tex = texture();
  int compared = 0;
  for (int k = 0; k < 20; ++k) {
    const Segmentation left = segmenter->segment(frame(tex, k), timeOf(k), 0);
    const Segmentation right = segmenter->segment(frame(tex, k + 1), timeOf(k), 1);
    // Same backend ids in both images here: the same instances, missed and injected.
    EXPECT_EQ(cv::countNonZero(left.ids != right.ids), 0) << k;
    EXPECT_EQ(left.instances, right.instances) << k;
    compared += static_cast<int>(left.instances.size());
  }
  EXPECT_GT(compared, 20);
}

TEST(SegmenterErrors, ANetworksFalseObjectsAreNumberedAfreshInEachFrame) {
  SegmenterErrorOptions options;
  options.false_objects_per_frame = 3.0;
  options.false_object_frames = 4;
  const auto segmenter = wrapped(options, /*ids_name_objects=*/false);
  const cv::Mat tex = texture();
  for (int k = 0; k < 10; ++k) {
    const Segmentation s = segmenter->segment(frame(tex, k), timeOf(k), 0);
    int expected = kInjectedObjectIdBase;
    for (const FalseObject& object : segmenter->falseObjects())
      EXPECT_EQ(object.id, expected++);
    EXPECT_LE(countInjected(s), static_cast<int>(segmenter->falseObjects().size()));
  }
}

TEST(SegmenterErrors, ABackendIdInTheInjectedRangeIsAnError) {
  cv::Mat ids(480, 640, CV_16UC1, cv::Scalar(0));
  ids(cv::Rect(10, 10, 20, 20)).setTo(kInjectedObjectIdBase + 5);
  SegmenterErrorOptions options;
  options.false_objects_per_frame = 1.0;
  ErrorInjectingSegmenter segmenter(std::make_unique<FixedSegmenter>(true, ids), options);
  const cv::Mat image(480, 640, CV_8UC1, cv::Scalar(100));
  EXPECT_THROW(segmenter.segment(image, timeOf(0), 0), InputError);
}

TEST(SegmenterErrors, InvalidOptionsNameTheirKey) {
  const auto expectKey = [](SegmenterErrorOptions options, const std::string& key) {
    try {
      options.validate();
      ADD_FAILURE() << key << ": no error";
    } catch (const OptionError& e) {
      EXPECT_NE(std::string(e.what()).find(key), std::string::npos) << e.what();
    }
  };
  expectKey({.false_objects_per_frame = -1.0}, "semantics.error_false_objects_per_frame");
  expectKey({.false_object_frames = 0}, "semantics.error_false_object_frames");
  expectKey({.false_object_min_px = 2}, "semantics.error_false_object_min_px");
  expectKey({.false_object_min_px = 50, .false_object_max_px = 40},
            "semantics.error_false_object_max_px");
  expectKey({.miss_rate = 1.5}, "semantics.error_miss_rate");
  expectKey({.seed = -1}, "semantics.error_seed");
}

TEST(SegmenterErrors, SegmenterOptionsWrapAnyBackendWithTheErrors) {
  SegmenterOptions options;
  EXPECT_EQ(withPerturbation(options, std::make_unique<FixedSegmenter>(true))->description(),
            "fixed");
  options.mask_dilate = 1;
  options.errors.miss_rate = 0.1;
  const std::string description =
      withPerturbation(options, std::make_unique<FixedSegmenter>(true))->description();
  EXPECT_NE(description.find("masks dilated 1"), std::string::npos) << description;
  EXPECT_NE(description.find("10 % of the instances missed"), std::string::npos) << description;
  options.errors.miss_rate = 2.0;
  EXPECT_THROW(options.validate(), OptionError);
}

}  // namespace
}  // namespace superdyna::semantics
