#include "superdyna/semantics/segmenter_errors.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <opencv2/imgproc.hpp>
#include <optional>
#include <set>
#include <string>

#include "superdyna/core/error.h"

namespace superdyna::semantics {

namespace {

// What a stream of draws is for: streams of one frame never share their numbers.
constexpr std::uint64_t kMissDraws = 1;
constexpr std::uint64_t kBirthDraws = 2;

constexpr int kMaxCentreTries = 50;         // background pixels tried for a false object's centre
constexpr int kMaxTemplateSide = 64;        // [px] of the patch that tracks a false object
constexpr int kTrackRadiusPx = 32;          // [px] search radius of that patch in the next image
constexpr double kMinTrackScore = 0.6;      // normalised cross-correlation of a trusted match
constexpr double kMinTemplateStddev = 2.0;  // gray levels: flatter patches are not tracked

/// SplitMix64 (Steele et al. 2014): a fixed integer recurrence, so the draws are the same with
/// every compiler and standard library (std:: distributions are implementation-defined).
std::uint64_t splitMix(std::uint64_t& state) {
  state += 0x9E3779B97F4A7C15ULL;
  std::uint64_t z = state;
  z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
  z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
  return z ^ (z >> 31);
}

/// The random draws of one (seed, frame time, purpose, key).
class Draws {
 public:
  Draws(int seed, TimeNs t_ns, std::uint64_t purpose, std::uint64_t key = 0) {
    state_ = static_cast<std::uint64_t>(seed);
    for (const std::uint64_t part : {static_cast<std::uint64_t>(t_ns), purpose, key})
      state_ = splitMix(state_) ^ part;
  }
  std::uint64_t next() { return splitMix(state_); }
  /// Uniform in [0, 1), from the upper 53 bits.
  double uniform() { return static_cast<double>(next() >> 11) * 0x1.0p-53; }
  double uniform(double lo, double hi) { return lo + (hi - lo) * uniform(); }
  /// Poisson with this mean (Knuth's product of uniforms; means up to 50, see validate()).
  int poisson(double mean) {
    const double limit = std::exp(-mean);
    int k = 0;
    for (double product = uniform(); product > limit; product *= uniform())
      ++k;
    return k;
  }

 private:
  std::uint64_t state_ = 0;
};

cv::Mat grayOf(const cv::Mat& image) {
  if (image.channels() == 1) return image;
  cv::Mat gray;
  cv::cvtColor(image, gray, image.channels() == 4 ? cv::COLOR_BGRA2GRAY : cv::COLOR_BGR2GRAY);
  return gray;
}

/// The ellipse shape of a false object of `class_id` with longer side `side` [px].
cv::Size2d halfAxesOf(int class_id, double side, Draws& draws) {
  if (class_id == sensors::kInstanceClassVehicle) {
    return {0.5 * side, 0.5 * side * draws.uniform(0.45, 0.75)};  // wider than tall
  }
  return {0.5 * side * draws.uniform(0.3, 0.5), 0.5 * side};  // a standing person
}

/// A background pixel of `ids` drawn uniformly (up to kMaxCentreTries), or none.
std::optional<cv::Point2d> backgroundPixel(const cv::Mat& ids, Draws& draws) {
  for (int attempt = 0; attempt < kMaxCentreTries; ++attempt) {
    const int c = std::min(ids.cols - 1, static_cast<int>(draws.uniform() * ids.cols));
    const int r = std::min(ids.rows - 1, static_cast<int>(draws.uniform() * ids.rows));
    if (ids.at<std::uint16_t>(r, c) == 0) return cv::Point2d(c, r);
  }
  return std::nullopt;
}

bool insideImage(const cv::Point2d& p, const cv::Size& size) {
  return p.x >= 0.0 && p.y >= 0.0 && p.x < size.width && p.y < size.height;
}

/// Where the patch around `object` in `previous` moved to in `current` (its centre unchanged
/// when the patch is flat or the best match is weak).
cv::Point2d trackedCentre(const FalseObject& object, const cv::Mat& previous,
                          const cv::Mat& current) {
  const cv::Rect image(0, 0, current.cols, current.rows);
  const int w = std::min(kMaxTemplateSide, static_cast<int>(2.0 * object.half_axes.width));
  const int h = std::min(kMaxTemplateSide, static_cast<int>(2.0 * object.half_axes.height));
  const cv::Rect patch = cv::Rect(static_cast<int>(std::lround(object.centre.x)) - w / 2,
                                  static_cast<int>(std::lround(object.centre.y)) - h / 2, w, h) &
                         image;
  if (patch.width < 4 || patch.height < 4) return object.centre;
  cv::Scalar mean, stddev;
  cv::meanStdDev(previous(patch), mean, stddev);
  if (stddev[0] < kMinTemplateStddev) return object.centre;
  const cv::Rect search =
      cv::Rect(patch.x - kTrackRadiusPx, patch.y - kTrackRadiusPx, patch.width + 2 * kTrackRadiusPx,
               patch.height + 2 * kTrackRadiusPx) &
      image;
  cv::Mat scores;
  cv::matchTemplate(current(search), previous(patch), scores, cv::TM_CCOEFF_NORMED);
  double best = 0.0;
  cv::Point at;
  cv::minMaxLoc(scores, nullptr, &best, nullptr, &at);
  if (!(best >= kMinTrackScore)) return object.centre;
  return object.centre + cv::Point2d(search.x + at.x - patch.x, search.y + at.y - patch.y);
}

/// The median score of the real instances (1 without any): false objects look like real ones.
float medianScore(const Segmentation& segmentation) {
  std::vector<float> scores;
  for (const Instance& instance : segmentation.instances)
    scores.push_back(instance.score);
  if (scores.empty()) return 1.0f;
  std::nth_element(scores.begin(), scores.begin() + static_cast<long>(scores.size() / 2),
                   scores.end());
  return scores[scores.size() / 2];
}

/// Throws when the backend's ids reach the range of injected objects.
void requireIdsBelowInjectedRange(const Segmentation& segmentation, const std::string& backend) {
  for (const Instance& instance : segmentation.instances) {
    if (instance.id >= kInjectedObjectIdBase) {
      throw InputError(fmt::format(
          "segmenter {} gave instance id {}, in the range {}..{} of injected false objects "
          "(semantics.error_false_objects_per_frame needs smaller ids)",
          backend, instance.id, kInjectedObjectIdBase, kInjectedObjectIdLast));
    }
  }
}

/// A fresh id in the injected range drawn from `draws`, none of the `living` objects'.
int freshId(const std::vector<FalseObject>& living_objects, Draws& draws) {
  std::set<int> living;
  for (const FalseObject& object : living_objects)
    living.insert(object.id);
  // Drawn rather than counted, so that without persistence a frame's ids depend on (seed, t_ns)
  // only; the next free id after the draw when a living object has it.
  constexpr auto kIds =
      static_cast<std::uint64_t>(kInjectedObjectIdLast - kInjectedObjectIdBase + 1);
  int id = kInjectedObjectIdBase + static_cast<int>(draws.next() % kIds);
  while (living.contains(id))
    id = id == kInjectedObjectIdLast ? kInjectedObjectIdBase : id + 1;
  return id;
}

}  // namespace

void SegmenterErrorOptions::validate() const {
  if (!(false_objects_per_frame >= 0.0 && false_objects_per_frame <= 50.0)) {
    throw OptionError("semantics.error_false_objects_per_frame", "must be in [0, 50]");
  }
  if (false_object_frames < 1) {
    throw OptionError("semantics.error_false_object_frames", "must be >= 1");
  }
  if (false_object_min_px < 4) {
    throw OptionError("semantics.error_false_object_min_px", "must be >= 4");
  }
  if (false_object_max_px < false_object_min_px) {
    throw OptionError("semantics.error_false_object_max_px",
                      "must be >= semantics.error_false_object_min_px");
  }
  if (!(miss_rate >= 0.0 && miss_rate <= 1.0)) {
    throw OptionError("semantics.error_miss_rate", "must be in [0, 1]");
  }
  if (seed < 0) throw OptionError("semantics.error_seed", "must be >= 0");
}

void removeMissedInstances(Segmentation& segmentation, const SegmenterErrorOptions& options,
                           TimeNs t_ns) {
  if (options.miss_rate <= 0.0) return;
  std::vector<Instance> kept;
  std::vector<int> missed;
  for (Instance& instance : segmentation.instances) {
    // One draw per (frame, id): an id naming one object in both images is missed in both.
    Draws draws(options.seed, t_ns, kMissDraws, static_cast<std::uint64_t>(instance.id));
    if (draws.uniform() < options.miss_rate) {
      missed.push_back(instance.id);
    } else {
      kept.push_back(std::move(instance));
    }
  }
  segmentation.instances = std::move(kept);
  if (missed.empty()) return;
  segmentation.ids = segmentation.ids.clone();  // never change the backend's (cached) image
  for (const int id : missed)
    segmentation.ids.setTo(0, segmentation.ids == id);
}

void paintFalseObjects(Segmentation& segmentation, const cv::Mat& background_ids,
                       const std::vector<FalseObject>& objects, float score) {
  if (objects.empty()) return;
  if (segmentation.ids.data == background_ids.data) segmentation.ids = segmentation.ids.clone();
  cv::Mat& ids = segmentation.ids;
  for (const FalseObject& object : objects) {
    const double a = object.half_axes.width, b = object.half_axes.height;
    const int c0 = std::max(0, static_cast<int>(std::ceil(object.centre.x - a)));
    const int c1 = std::min(ids.cols - 1, static_cast<int>(std::floor(object.centre.x + a)));
    const int r0 = std::max(0, static_cast<int>(std::ceil(object.centre.y - b)));
    const int r1 = std::min(ids.rows - 1, static_cast<int>(std::floor(object.centre.y + b)));
    for (int r = r0; r <= r1; ++r) {
      const double dy = (r - object.centre.y) / b;
      const auto* background = background_ids.ptr<std::uint16_t>(r);
      auto* row = ids.ptr<std::uint16_t>(r);
      for (int c = c0; c <= c1; ++c) {
        const double dx = (c - object.centre.x) / a;
        if (dx * dx + dy * dy <= 1.0 && background[c] == 0 && row[c] == 0)
          row[c] = static_cast<std::uint16_t>(object.id);
      }
    }
    Instance instance;
    instance.id = object.id;
    instance.class_id = object.class_id;
    instance.label = fmt::format("injected_{}", sensors::instanceClassName(object.class_id));
    instance.score = score;
    segmentation.instances.push_back(std::move(instance));
  }
  std::sort(segmentation.instances.begin(), segmentation.instances.end(),
            [](const Instance& x, const Instance& y) { return x.id < y.id; });
  updateBoxesAndAreas(segmentation);  // boxes and areas; objects without a pixel are dropped
}

ErrorInjectingSegmenter::ErrorInjectingSegmenter(std::unique_ptr<Segmenter> segmenter,
                                                 const SegmenterErrorOptions& options)
    : segmenter_(std::move(segmenter)), options_(options) {
  options_.validate();
}

Segmentation ErrorInjectingSegmenter::segment(const cv::Mat& image, TimeNs t_ns, int camera) {
  Segmentation segmentation = segmenter_->segment(image, t_ns, camera);
  if (segmentation.ids.empty()) segmentation.ids = cv::Mat::zeros(image.size(), CV_16UC1);
  const std::lock_guard lock(mutex_);
  const bool false_objects = options_.false_objects_per_frame > 0.0;
  if (false_objects) requireIdsBelowInjectedRange(segmentation, segmenter_->description());
  const cv::Mat original = segmentation.ids;  // the backend's background, before any miss
  const float score = medianScore(segmentation);
  removeMissedInstances(segmentation, options_, t_ns);
  if (!false_objects) return segmentation;
  const bool same_frame = has_frame_ && t_ns == last_t_ns_;
  if (camera == 0 && !same_frame) advance(grayOf(image), original, t_ns);
  // The right image (or a left one segmented again) shows the false objects of its left image.
  if (has_frame_ && t_ns == last_t_ns_) paintFalseObjects(segmentation, original, objects_, score);
  return segmentation;
}

void ErrorInjectingSegmenter::advance(const cv::Mat& gray, const cv::Mat& background, TimeNs t_ns) {
  const bool first_frame = !has_frame_ || t_ns < last_t_ns_ || gray.size() != last_gray_.size();
  if (first_frame) {
    objects_.clear();
  } else {
    trackObjects(gray);
  }
  addBirths(background, t_ns, first_frame);
  if (!segmenter_->idsNameObjects()) {
    // A network numbers each image afresh: so do its false objects.
    for (std::size_t i = 0; i < objects_.size(); ++i)
      objects_[i].id = kInjectedObjectIdBase + static_cast<int>(i);
  }
  last_gray_ = gray.clone();
  last_t_ns_ = t_ns;
  has_frame_ = true;
}

void ErrorInjectingSegmenter::trackObjects(const cv::Mat& gray) {
  std::vector<FalseObject> living;
  for (FalseObject& object : objects_) {
    if (--object.frames_left <= 0) continue;  // its life is over: it vanishes
    object.centre = trackedCentre(object, last_gray_, gray);
    if (insideImage(object.centre, gray.size())) living.push_back(object);
  }
  objects_ = std::move(living);
}

void ErrorInjectingSegmenter::addBirths(const cv::Mat& background, TimeNs t_ns, bool first_frame) {
  Draws draws(options_.seed, t_ns, kBirthDraws);
  const int lifetime = options_.false_object_frames;
  // The first frame starts in the steady state: the mean number present, with remaining lives
  // spread over 1..lifetime; later frames add the births that keep that mean.
  const double mean =
      first_frame ? options_.false_objects_per_frame : options_.false_objects_per_frame / lifetime;
  const int births = draws.poisson(mean);
  for (int i = 0; i < births; ++i) {
    FalseObject object;
    object.class_id =
        draws.uniform() < 0.5 ? sensors::kInstanceClassVehicle : sensors::kInstanceClassPedestrian;
    const double side = draws.uniform(options_.false_object_min_px, options_.false_object_max_px);
    object.half_axes = halfAxesOf(object.class_id, side, draws);
    // Drawn in every frame, so that the draws after it do not depend on being the first frame.
    const double life_draw = draws.uniform();
    object.frames_left =
        first_frame ? 1 + std::min(lifetime - 1, static_cast<int>(life_draw * lifetime)) : lifetime;
    const std::optional<cv::Point2d> centre = backgroundPixel(background, draws);
    if (!centre) continue;
    object.centre = *centre;
    object.id = freshId(objects_, draws);
    objects_.push_back(object);
  }
}

std::vector<FalseObject> ErrorInjectingSegmenter::falseObjects() const {
  const std::lock_guard lock(mutex_);
  return objects_;
}

std::string ErrorInjectingSegmenter::description() const {
  return fmt::format(
      "{}, with simulated errors: {} false objects per frame ({}-{} px, living {} frames), {} % "
      "of the instances missed, seed {}",
      segmenter_->description(), options_.false_objects_per_frame, options_.false_object_min_px,
      options_.false_object_max_px, options_.false_object_frames, 100.0 * options_.miss_rate,
      options_.seed);
}

}  // namespace superdyna::semantics
