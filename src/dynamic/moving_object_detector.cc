#include "superdyna/dynamic/moving_object_detector.h"

#include <fmt/format.h>

#include <Eigen/Geometry>
#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <random>
#include <set>
#include <tuple>

#include "superdyna/core/error.h"
#include "superdyna/dynamic/relative_motion.h"
#include "superdyna/features/matcher.h"

namespace superdyna::dynamic {

namespace {

constexpr int kNumTests = kResidualTestCount;
constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

int index(ResidualTest test) {
  return static_cast<int>(test);
}

bool isMovable(const features::Keypoint& keypoint) {
  return keypoint.class_id != features::kClassBackground;
}

bool finite(const Eigen::Vector2d& x) {
  return std::isfinite(x.x()) && std::isfinite(x.y());
}

double median(std::vector<double> values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

/// SplitMix64: a seed per frame from the option seed and the frame time, so that the draw does
/// not depend on how many frames came before (and is the same on every platform).
std::uint64_t mixSeed(std::uint64_t seed, TimeNs t_ns) {
  std::uint64_t z = seed + 0x9e3779b97f4a7c15ULL * (static_cast<std::uint64_t>(t_ns) + 1);
  z = (z ^ (z >> 30)) * 0xbf58476d1ce4e5b9ULL;
  z = (z ^ (z >> 27)) * 0x94d049bb133111ebULL;
  return z ^ (z >> 31);
}

/// The first `count` elements of a seeded partial Fisher-Yates shuffle of `items` (modulo draw:
/// the bias is negligible for the few dozen pairs of an object, and the result is portable).
template <class T>
std::vector<T> drawSubset(std::vector<T> items, std::size_t count, std::uint64_t seed) {
  std::mt19937_64 rng(seed);
  count = std::min(count, items.size());
  for (std::size_t i = 0; i < count; ++i) {
    const std::size_t j = i + static_cast<std::size_t>(rng() % (items.size() - i));
    std::swap(items[i], items[j]);
  }
  items.resize(count);
  return items;
}

}  // namespace

DynamicMode parseDynamicMode(const std::string& name, const std::string& option) {
  if (name == "off") return DynamicMode::kOff;
  if (name == "semantic") return DynamicMode::kSemantic;
  if (name == "semantic-geometric") return DynamicMode::kSemanticGeometric;
  throw OptionError(option,
                    fmt::format("unknown mode '{}' (off|semantic|semantic-geometric)", name));
}

std::string toString(DynamicMode mode) {
  switch (mode) {
    case DynamicMode::kOff:
      return "off";
    case DynamicMode::kSemantic:
      return "semantic";
    case DynamicMode::kSemanticGeometric:
      return "semantic-geometric";
  }
  return "?";
}

const char* toString(ObjectState state) {
  switch (state) {
    case ObjectState::kUnverified:
      return "unverified";
    case ObjectState::kStatic:
      return "static";
    case ObjectState::kMoving:
      return "moving";
  }
  return "?";
}

void MovingObjectOptions::validate() const {
  const auto require = [](bool ok, const char* option, const char* what) {
    if (!ok) throw OptionError(std::string("dynamic.") + option, what);
  };
  require(min_pairs >= 1, "min_pairs", "must be >= 1");
  require(max_tested_pairs >= 1, "max_tested_pairs", "must be >= 1");
  require(clear_static_pairs >= 0, "clear_static_pairs", "must be >= 0");
  require(max_pedestrian_speed_mps > 0.0, "max_pedestrian_speed_mps", "must be > 0");
  require(max_vehicle_speed_mps > 0.0, "max_vehicle_speed_mps", "must be > 0");
  require(threshold_scale > 0.0, "threshold_scale", "must be > 0");
  require(min_threshold_px > 0.0, "min_threshold_px", "must be > 0");
  require(fallback_threshold_px > 0.0, "fallback_threshold_px", "must be > 0");
  require(min_background_pairs >= 1, "min_background_pairs", "must be >= 1");
  require(moving_vote_share > 0.0 && moving_vote_share <= 1.0, "moving_vote_share",
          "must be in (0, 1]");
  require(min_votes >= 1, "min_votes", "must be >= 1");
  require(min_translation_m >= 0.0, "min_translation_m", "must be >= 0");
  require(static_confirmations >= 1, "static_confirmations", "must be >= 1");
  require(moving_confirmations >= 1, "moving_confirmations", "must be >= 1");
  require(background_radius_px > 0.0, "background_radius_px", "must be > 0");
  require(object_search_radius_px > 0.0, "object_search_radius_px", "must be > 0");
  require(match_ratio > 0.0 && match_ratio <= 1.0, "match_ratio", "must be in (0, 1]");
  require(max_hamming >= 0, "max_hamming", "must be >= 0");
  require(max_l2_distance >= 0.0, "max_l2_distance", "must be >= 0");
  require(seed >= 0, "seed", "must be >= 0");
  require(baseline_frames >= 1 && baseline_frames <= kMaxBaselineFrames, "baseline_frames",
          fmt::format("must be in [1, {}]", kMaxBaselineFrames).c_str());
  require(geometric_cell_px >= 8, "geometric_cell_px", "must be >= 8");
  require(geometric_min_outliers >= 1, "geometric_min_outliers", "must be >= 1");
  require(geometric_outlier_share > 0.0 && geometric_outlier_share <= 1.0,
          "geometric_outlier_share", "must be in (0, 1]");
  require(geometric_threshold_factor >= 1.0, "geometric_threshold_factor", "must be >= 1");
}

MovingObjectDetector::MovingObjectDetector(const MovingObjectOptions& options,
                                           const CameraModel& camera, double pyramid_scale_factor)
    : options_(options),
      camera_(camera),
      focal_px_(0.5 * (camera.fx() + camera.fy())),
      pyramid_scale_factor_(pyramid_scale_factor) {
  options_.validate();
  if (!(pyramid_scale_factor >= 1.0)) {
    throw OptionError("orb.scale_factor", "the moving-object test needs a pyramid scale >= 1");
  }
}

double MovingObjectDetector::linkScale(const Link& link, const FrameObservations& current) const {
  const int octave = std::max(
      link.from.octave, current.features->keypoints[static_cast<std::size_t>(link.current)].octave);
  return std::pow(pyramid_scale_factor_, octave);
}

void MovingObjectDetector::reset() {
  chains_.clear();
  earlier_.clear();
  tracks_.clear();
  track_of_previous_instance_.clear();
}

std::optional<Eigen::Vector2d> MovingObjectDetector::staticLanding(
    const FrameObservations& previous, std::size_t i, const SE3d& T_cur_prev) const {
  const Eigen::Vector2d& x = (*previous.normalized)[i];
  if (!finite(x)) return std::nullopt;
  const Eigen::Vector3d p_cur = previous.hasDepth(i)
                                    ? Eigen::Vector3d(T_cur_prev * (*previous.p_c)[i])
                                    : Eigen::Vector3d(T_cur_prev.q * x.homogeneous());
  return camera_.project(p_cur);
}

std::vector<MovingObjectDetector::Pair> MovingObjectDetector::matchPairs(
    const FrameObservations& previous, const FrameObservations& current, const SE3d& T_cur_prev,
    bool movable, bool wide, const std::vector<Pair>& already) const {
  std::vector<char> query(previous.features->size(), 0);
  for (std::size_t i = 0; i < query.size(); ++i)
    query[i] = isMovable(previous.features->keypoints[i]) == movable;
  for (const Pair& pair : already)
    query[static_cast<std::size_t>(pair.previous)] = 0;
  // Candidates of the same kind only (movable or background): the wide object search would
  // otherwise sort through every keypoint within 120 px.
  std::vector<char> candidate(current.features->size(), 0);
  for (std::size_t j = 0; j < candidate.size(); ++j)
    candidate[j] = isMovable(current.features->keypoints[j]) == movable;
  const double radius = wide              ? options_.object_search_radius_px
                        : current.depth_m ? options_.background_radius_px
                                          : 2.0 * options_.background_radius_px;
  return searchPairs(previous, current, T_cur_prev, query, candidate, radius, true);
}

std::vector<MovingObjectDetector::Pair> MovingObjectDetector::searchPairs(
    const FrameObservations& previous, const FrameObservations& current, const SE3d& T_cur_prev,
    const std::vector<char>& query, std::vector<char> candidate, double radius_px,
    bool same_class_only) const {
  std::vector<Eigen::Vector2d> predicted(query.size(), Eigen::Vector2d::Constant(kNaN));
  for (std::size_t i = 0; i < query.size(); ++i) {
    if (!query[i]) continue;
    if (const auto pixel = staticLanding(previous, i, T_cur_prev)) predicted[i] = *pixel;
  }
  features::ProjectionMatchOptions search;
  search.radius_px = radius_px;
  search.ratio = options_.match_ratio;
  search.max_distance = options_.max_hamming;
  search.max_l2_distance = options_.max_l2_distance;
  search.same_class_only = same_class_only;
  const std::vector<features::Keypoint>& keypoints = current.features->keypoints;
  for (std::size_t j = 0; j < keypoints.size(); ++j)
    candidate[j] = candidate[j] && finite((*current.normalized)[j]);
  // Cells of half the radius keep a wide query to a few cells.
  const int cell_px = std::max(20, static_cast<int>(search.radius_px / 2.0));
  const features::KeypointGrid grid(keypoints, current.features->image_size, cell_px, candidate);
  std::vector<Pair> pairs;
  for (const features::Match& match : features::matchByProjection(
           *previous.features, predicted, *current.features, grid, search)) {
    pairs.push_back({match.query, match.train});
  }
  return pairs;
}

std::set<int> MovingObjectDetector::addBackgroundPairsOfUnpairedObjects(
    const FrameObservations& previous, const FrameObservations& current, const SE3d& T_cur_prev,
    std::map<int, std::vector<Pair>>& pairs_of) const {
  // The objects without enough pairs among the previous frame's movable keypoints, and the box
  // of each one's keypoints widened by the background search radius.
  const std::vector<features::Keypoint>& keypoints = current.features->keypoints;
  std::map<int, Eigen::AlignedBox2d> boxes;
  for (const features::Keypoint& keypoint : keypoints) {
    if (!isMovable(keypoint)) continue;
    const auto found = pairs_of.find(keypoint.instance_id);
    const int paired = found == pairs_of.end() ? 0 : static_cast<int>(found->second.size());
    if (paired < options_.min_pairs) boxes[keypoint.instance_id].extend(keypoint.pixel);
  }
  if (boxes.empty()) return {};
  const Eigen::Vector2d margin = Eigen::Vector2d::Constant(options_.background_radius_px);
  for (auto& [instance, box] : boxes)
    box = Eigen::AlignedBox2d(box.min() - margin, box.max() + margin);
  // Previous background keypoints that would land in such a box if they stood still: the
  // object's own points if the segmenter missed it (or made it up) in the previous frame.
  std::vector<char> query(previous.features->size(), 0);
  for (std::size_t i = 0; i < query.size(); ++i) {
    if (isMovable(previous.features->keypoints[i])) continue;
    const auto pixel = staticLanding(previous, i, T_cur_prev);
    if (!pixel) continue;
    query[i] = std::any_of(boxes.begin(), boxes.end(),
                           [&](const auto& entry) { return entry.second.contains(*pixel); });
  }
  std::vector<char> candidate(keypoints.size(), 0);
  for (std::size_t j = 0; j < keypoints.size(); ++j)
    candidate[j] = isMovable(keypoints[j]) && boxes.count(keypoints[j].instance_id);
  std::set<int> paired;
  for (const Pair& pair : searchPairs(previous, current, T_cur_prev, query, candidate,
                                      options_.object_search_radius_px, false)) {
    const int instance = keypoints[static_cast<std::size_t>(pair.current)].instance_id;
    pairs_of[instance].push_back(pair);
    paired.insert(instance);
  }
  return paired;
}

SE3d MovingObjectDetector::refinedMotion(const std::vector<Pair>& background,
                                         const FrameObservations& previous,
                                         const FrameObservations& current,
                                         const SE3d& T_cur_prev) const {
  std::vector<Eigen::Vector3d> points;
  std::vector<Eigen::Vector2d> observed;
  for (const Pair& pair : background) {
    if (!previous.hasDepth(pair.previous)) continue;
    points.push_back((*previous.p_c)[pair.previous]);
    observed.push_back((*current.normalized)[pair.current]);
  }
  return refineRelativePose(points, observed, T_cur_prev, focal_px_);
}

MovingObjectDetector::Endpoint MovingObjectDetector::endpointOf(const FrameObservations& frame,
                                                                int i) const {
  const auto k = static_cast<std::size_t>(i);
  Endpoint end;
  end.x = (*frame.normalized)[k];
  end.has_depth = frame.hasDepth(k);
  if (end.has_depth) end.p = (*frame.p_c)[k];
  end.octave = frame.features->keypoints[k].octave;
  end.on_border = frame.features->keypoints[k].on_instance_border;
  return end;
}

std::vector<MovingObjectDetector::Link> MovingObjectDetector::linksOf(
    const std::vector<Pair>& pairs, const FrameObservations& previous) const {
  std::vector<Link> links;
  links.reserve(pairs.size());
  for (const Pair& pair : pairs)
    links.push_back({endpointOf(previous, pair.previous), pair.current});
  return links;
}

int MovingObjectDetector::chainDepth(const Pair& pair) const {
  const auto k = static_cast<std::size_t>(pair.previous);
  return k < chains_.size() ? chains_[k].size : 0;
}

std::vector<MovingObjectDetector::Link> MovingObjectDetector::linksAtDepth(
    const std::vector<Pair>& pairs, const FrameObservations& previous, int depth) const {
  if (depth == 0) return linksOf(pairs, previous);
  std::vector<Link> links;
  for (const Pair& pair : pairs) {
    if (chainDepth(pair) < depth) continue;
    const Chain& chain = chains_[static_cast<std::size_t>(pair.previous)];
    links.push_back({chain.ends[static_cast<std::size_t>(depth - 1)], pair.current});
  }
  return links;
}

MovingObjectDetector::Thresholds MovingObjectDetector::backgroundThresholds(
    const std::vector<Link>& links, const FrameObservations& current,
    const SE3d& T_cur_from) const {
  std::array<std::vector<double>, kNumTests> residuals;
  const bool translating = T_cur_from.t.norm() >= options_.min_translation_m;
  for (const Link& link : links) {
    const Eigen::Vector2d& x_from = link.from.x;
    const Eigen::Vector2d& x_cur = (*current.normalized)[static_cast<std::size_t>(link.current)];
    const double scale = linkScale(link, current);
    const auto push = [&](ResidualTest test, std::optional<double> residual) {
      if (residual) residuals[index(test)].push_back(*residual / scale);
    };
    if (translating) {
      push(ResidualTest::kEpipolar, epipolarRayDistancePx(x_from, x_cur, T_cur_from, focal_px_));
    } else {
      push(ResidualTest::kRotationTransfer,
           rotationTransferDistancePx(x_from, x_cur, T_cur_from, focal_px_));
    }
    if (link.from.has_depth) {
      push(ResidualTest::kReprojection,
           reprojectionDistancePx(link.from.p, x_cur, T_cur_from, focal_px_));
    }
  }
  Thresholds thresholds;
  for (int test = 0; test < kNumTests; ++test) {
    const std::vector<double>& values = residuals[test];
    thresholds.samples[test] = static_cast<int>(values.size());
    thresholds.px[test] =
        static_cast<int>(values.size()) < options_.min_background_pairs
            ? options_.fallback_threshold_px
            : std::max(options_.min_threshold_px, options_.threshold_scale * median(values));
  }
  return thresholds;
}

std::optional<std::pair<double, double>> MovingObjectDetector::linkResidual(
    const Link& link, const FrameObservations& current, const SE3d& T_cur_from,
    const Thresholds& thresholds) const {
  const bool translating = T_cur_from.t.norm() >= options_.min_translation_m;
  const Eigen::Vector2d& x_cur = (*current.normalized)[static_cast<std::size_t>(link.current)];
  ResidualTest test = translating ? ResidualTest::kEpipolar : ResidualTest::kRotationTransfer;
  std::optional<double> residual;
  if (options_.stereo_reprojection && link.from.has_depth) {
    test = ResidualTest::kReprojection;
    residual = reprojectionDistancePx(link.from.p, x_cur, T_cur_from, focal_px_);
  } else if (translating) {
    residual = epipolarRayDistancePx(link.from.x, x_cur, T_cur_from, focal_px_);
  } else {
    residual = rotationTransferDistancePx(link.from.x, x_cur, T_cur_from, focal_px_);
  }
  if (!residual) return std::nullopt;
  return std::make_pair(*residual, linkScale(link, current) * thresholds.px[index(test)]);
}

std::vector<MovingObjectDetector::Link> MovingObjectDetector::testableLinks(
    const std::vector<Link>& links, const FrameObservations& current) const {
  if (!options_.skip_border_pairs) return links;
  std::vector<Link> inner;
  for (const Link& link : links) {
    const auto k = static_cast<std::size_t>(link.current);
    if (!link.from.on_border && !current.features->keypoints[k].on_instance_border)
      inner.push_back(link);
  }
  return inner.empty() ? links : inner;
}

std::vector<MovingObjectDetector::Link> MovingObjectDetector::plausibleLinks(
    const std::vector<Link>& links, const FrameObservations& current, const Baseline& baseline,
    int class_id) const {
  if (!(baseline.dt_s > 0.0)) return links;
  const double max_speed = class_id == features::kClassPedestrian
                               ? options_.max_pedestrian_speed_mps
                               : options_.max_vehicle_speed_mps;
  std::vector<Link> plausible;
  plausible.reserve(links.size());
  for (const Link& link : links) {
    if (link.from.has_depth) {
      const Eigen::Vector3d p_cur = baseline.T_cur_from * link.from.p;
      const auto residual = reprojectionDistancePx(
          link.from.p, (*current.normalized)[static_cast<std::size_t>(link.current)],
          baseline.T_cur_from, focal_px_);
      // The motion across the ray at the point's depth: a lower bound of its speed.
      if (residual && *residual / focal_px_ * p_cur.z() > max_speed * baseline.dt_s) continue;
    }
    plausible.push_back(link);
  }
  return plausible;
}

void MovingObjectDetector::testObject(const std::vector<Link>& links,
                                      const FrameObservations& current, const Baseline& baseline,
                                      std::uint64_t draw_seed, int max_tested,
                                      ObjectDecision& decision) const {
  const std::vector<Link> drawn = drawSubset(
      testableLinks(plausibleLinks(links, current, baseline, decision.class_id), current),
      static_cast<std::size_t>(std::max(0, max_tested)), draw_seed);
  double worst_excess = decision.tested > 0 ? decision.max_distance_px - decision.threshold_px
                                            : -std::numeric_limits<double>::infinity();
  for (const Link& link : drawn) {
    const auto tested = linkResidual(link, current, baseline.T_cur_from, baseline.thresholds);
    if (!tested) continue;
    const auto [residual, threshold] = *tested;
    ++decision.tested;
    if (residual > threshold) ++decision.votes;
    if (residual - threshold > worst_excess) {
      worst_excess = residual - threshold;
      decision.max_distance_px = residual;
      decision.threshold_px = threshold;
    }
  }
}

std::vector<char> MovingObjectDetector::movingBackgroundCells(const std::vector<Link>& background,
                                                              const FrameObservations& current,
                                                              const SE3d& T_cur_prev,
                                                              const Thresholds& thresholds,
                                                              MovingObjectReport& report) const {
  const cv::Size size = current.features->image_size;
  std::vector<int> outliers(cellCount(size), 0);
  std::vector<int> tested(outliers.size(), 0);
  for (const Link& link : background) {
    const auto result = linkResidual(link, current, T_cur_prev, thresholds);
    if (!result) continue;
    const std::size_t k =
        cellOf(current.features->keypoints[static_cast<std::size_t>(link.current)].pixel, size);
    ++tested[k];
    if (result->first > options_.geometric_threshold_factor * result->second) ++outliers[k];
  }
  std::vector<char> moving(outliers.size(), 0);
  for (std::size_t k = 0; k < moving.size(); ++k) {
    moving[k] = outliers[k] >= options_.geometric_min_outliers &&
                outliers[k] >= options_.geometric_outlier_share * tested[k];
    report.moving_background_cells += moving[k];
  }
  return moving;
}

cv::Size MovingObjectDetector::cellGrid(cv::Size image_size) const {
  const int cell = options_.geometric_cell_px;
  return {(image_size.width + cell - 1) / cell, (image_size.height + cell - 1) / cell};
}

std::size_t MovingObjectDetector::cellCount(cv::Size image_size) const {
  return static_cast<std::size_t>(cellGrid(image_size).area());
}

std::size_t MovingObjectDetector::cellOf(const Eigen::Vector2d& pixel, cv::Size image_size) const {
  const int cell = options_.geometric_cell_px;
  const cv::Size grid = cellGrid(image_size);
  const int c = std::clamp(static_cast<int>(pixel.x()) / cell, 0, grid.width - 1);
  const int r = std::clamp(static_cast<int>(pixel.y()) / cell, 0, grid.height - 1);
  return static_cast<std::size_t>(r * grid.width + c);
}

std::map<int, int> MovingObjectDetector::associateTracks(
    const std::map<int, std::vector<Pair>>& pairs_of, const std::vector<int>& instances,
    const FrameObservations* previous, const FrameObservations& current, const SE3d& T_cur_prev) {
  // Candidate links (pairs, current instance, previous instance), strongest first; each previous
  // instance hands its track to one current instance only, so that a few wrong matches cannot
  // give two objects one track (and one object's motion to another).
  std::vector<std::tuple<int, int, int>> links;
  if (previous) {
    for (const auto& [instance, pairs] : pairs_of) {
      std::map<int, int> votes;  // previous instance id -> pairs
      for (const Pair& pair : pairs)
        ++votes[previous->features->keypoints[pair.previous].instance_id];
      for (const auto& [previous_instance, count] : votes) {
        links.emplace_back(count, instance, previous_instance);
      }
    }
  }
  std::sort(links.begin(), links.end(), [](const auto& a, const auto& b) {
    if (std::get<0>(a) != std::get<0>(b)) return std::get<0>(a) > std::get<0>(b);
    return std::make_pair(std::get<1>(a), std::get<2>(a)) <
           std::make_pair(std::get<1>(b), std::get<2>(b));
  });
  std::map<int, int> track_of_instance;
  std::set<int> handed_on;
  for (const auto& [count, instance, previous_instance] : links) {
    const auto found = track_of_previous_instance_.find(previous_instance);
    if (found == track_of_previous_instance_.end() || track_of_instance.count(instance) ||
        handed_on.count(previous_instance)) {
      continue;
    }
    track_of_instance[instance] = found->second;
    handed_on.insert(previous_instance);
  }
  if (previous)
    inheritTracksByOverlap(*previous, current, T_cur_prev, handed_on, track_of_instance);
  for (const int instance : instances) {
    if (!track_of_instance.count(instance)) track_of_instance[instance] = next_track_++;
  }
  return track_of_instance;
}

void MovingObjectDetector::inheritTracksByOverlap(const FrameObservations& previous,
                                                  const FrameObservations& current,
                                                  const SE3d& T_cur_prev, std::set<int>& handed_on,
                                                  std::map<int, int>& track_of_instance) const {
  // Where every unclaimed previous object's keypoints land if they stand still, per instance.
  struct Landing {
    int class_id = 0;
    std::vector<Eigen::Vector2d> pixels;
  };
  std::map<int, Landing> landings;
  const std::vector<features::Keypoint>& before = previous.features->keypoints;
  for (std::size_t i = 0; i < before.size(); ++i) {
    const int id = before[i].instance_id;
    if (!isMovable(before[i]) || handed_on.count(id) || !track_of_previous_instance_.count(id)) {
      continue;
    }
    const auto pixel = staticLanding(previous, i, T_cur_prev);
    if (!pixel) continue;
    landings[id].class_id = before[i].class_id;
    landings[id].pixels.push_back(*pixel);
  }
  // Each current object without a track: the keypoints' box, widened by the background search
  // radius; the previous object of its class with the most landings inside (at least half of
  // its landings) hands on its track.
  std::map<int, Eigen::AlignedBox2d> boxes;
  std::map<int, int> class_of;
  for (const features::Keypoint& keypoint : current.features->keypoints) {
    if (!isMovable(keypoint) || track_of_instance.count(keypoint.instance_id)) continue;
    boxes[keypoint.instance_id].extend(keypoint.pixel);
    class_of[keypoint.instance_id] = keypoint.class_id;
  }
  const Eigen::Vector2d margin = Eigen::Vector2d::Constant(options_.background_radius_px);
  for (const auto& [instance, box] : boxes) {
    const Eigen::AlignedBox2d widened(box.min() - margin, box.max() + margin);
    int best = -1;
    std::size_t best_inside = 0;
    for (const auto& [id, landing] : landings) {
      if (landing.class_id != class_of[instance] || handed_on.count(id)) continue;
      const auto inside = static_cast<std::size_t>(
          std::count_if(landing.pixels.begin(), landing.pixels.end(),
                        [&](const Eigen::Vector2d& pixel) { return widened.contains(pixel); }));
      if (2 * inside >= landing.pixels.size() && inside > best_inside) {
        best = id;
        best_inside = inside;
      }
    }
    if (best < 0) continue;
    track_of_instance[instance] = track_of_previous_instance_.at(best);
    handed_on.insert(best);
  }
}

bool MovingObjectDetector::clearlyStatic(const ObjectDecision& decision) const {
  return options_.clear_static_pairs > 0 && decision.votes == 0 &&
         decision.tested >= options_.clear_static_pairs;
}

void MovingObjectDetector::applyHysteresis(ObjectDecision& decision, bool tested_moving) {
  Track& track = tracks_[decision.track_id];
  // A verified track's state changes only on frames with min_votes tested pairs or more: one pair
  // can be a mismatch; a new track takes what it has.
  const int conclusive = track.state == ObjectState::kUnverified ? 1 : options_.min_votes;
  if (decision.tested >= conclusive) {
    track.moving_run = tested_moving ? track.moving_run + 1 : 0;
    track.static_run = tested_moving ? 0 : track.static_run + 1;
    if (track.state != ObjectState::kStatic && tested_moving) {
      track.state = ObjectState::kMoving;
    } else if (track.state == ObjectState::kStatic &&
               track.moving_run >= options_.moving_confirmations) {
      track.state = ObjectState::kMoving;
    } else if (track.state != ObjectState::kMoving && !tested_moving) {
      track.state = ObjectState::kStatic;
    } else if (track.state == ObjectState::kMoving &&
               (track.static_run >= options_.static_confirmations || clearlyStatic(decision))) {
      track.state = ObjectState::kStatic;
    }
  }
  applyTrackState(decision);
}

void MovingObjectDetector::applyTrackState(ObjectDecision& decision) {
  const ObjectState state = tracks_[decision.track_id].state;
  decision.decision = state;
  decision.dropped = state == ObjectState::kMoving ||
                     (state == ObjectState::kUnverified && options_.drop_unverified);
}

void MovingObjectDetector::testObjects(const std::map<int, std::vector<Pair>>& pairs_of,
                                       const FrameObservations& previous,
                                       const FrameObservations& current,
                                       const std::vector<Baseline>& baselines,
                                       std::map<int, ObjectDecision>& objects) const {
  const std::uint64_t frame_seed = mixSeed(static_cast<std::uint64_t>(options_.seed), current.t_ns);
  for (auto& [instance, object] : objects) {
    const auto found = pairs_of.find(instance);
    if (found == pairs_of.end()) continue;
    object.pairs = static_cast<int>(found->second.size());
    if (object.pairs < options_.min_pairs) continue;
    const std::uint64_t seed = frame_seed ^ static_cast<std::uint64_t>(instance);
    // Each pair over the longest baseline its chain gives: a longer one multiplies a slow mover's
    // displacement. The longest are drawn first, the shorter fill the room left (an object seen
    // anew in the last frame would otherwise be judged on its one or two long links).
    for (int depth = static_cast<int>(baselines.size()) - 1; depth >= 0; --depth) {
      std::vector<Pair> at_depth;
      for (const Pair& pair : found->second) {
        if (std::min(chainDepth(pair), static_cast<int>(baselines.size()) - 1) == depth)
          at_depth.push_back(pair);
      }
      testObject(linksAtDepth(at_depth, previous, depth), current,
                 baselines[static_cast<std::size_t>(depth)],
                 mixSeed(seed, static_cast<TimeNs>(depth)),
                 options_.max_tested_pairs - object.tested, object);
    }
  }
}

std::vector<MovingObjectDetector::Baseline> MovingObjectDetector::baselinesOf(
    const std::vector<Pair>& background, const FrameObservations& previous,
    const FrameObservations& current, const SE3d& T_cur_prev) const {
  std::vector<Baseline> baselines{
      {T_cur_prev, backgroundThresholds(linksOf(background, previous), current, T_cur_prev),
       nsToSeconds(current.t_ns - previous.t_ns)}};
  for (std::size_t d = 0; d < earlier_.size(); ++d) {
    const SE3d T_cur_from = T_cur_prev * earlier_[d].T_last_from;
    const int depth = static_cast<int>(d) + 1;
    baselines.push_back(
        {T_cur_from,
         backgroundThresholds(linksAtDepth(background, previous, depth), current, T_cur_from),
         nsToSeconds(current.t_ns - earlier_[d].t_ns)});
  }
  return baselines;
}

void MovingObjectDetector::rememberChains(const std::vector<Pair>& pairs,
                                          const FrameObservations& previous,
                                          const FrameObservations& current,
                                          const SE3d& T_cur_prev) {
  const int longest = options_.baseline_frames - 1;
  if (longest == 0) return;  // the last frame only: nothing to chain
  std::vector<Chain> next(current.features->size());
  for (const Pair& pair : pairs) {
    Chain& chain = next[static_cast<std::size_t>(pair.current)];
    chain.ends[0] = endpointOf(previous, pair.previous);
    chain.size = 1;
    const auto k = static_cast<std::size_t>(pair.previous);
    if (k >= chains_.size()) continue;
    for (int d = 0; d < chains_[k].size && chain.size < longest; ++d) {
      chain.ends[static_cast<std::size_t>(chain.size++)] =
          chains_[k].ends[static_cast<std::size_t>(d)];
    }
  }
  std::vector<EarlierFrame> earlier{{previous.t_ns, T_cur_prev}};
  for (std::size_t d = 0; d < earlier_.size() && static_cast<int>(earlier.size()) < longest; ++d) {
    earlier.push_back({earlier_[d].t_ns, T_cur_prev * earlier_[d].T_last_from});
  }
  chains_ = std::move(next);
  earlier_ = std::move(earlier);
}

void MovingObjectDetector::dropKeypoints(const std::map<int, ObjectDecision>& objects,
                                         const std::vector<char>& moving_cells,
                                         const FrameObservations& current,
                                         MovingObjectReport& report) const {
  const std::vector<features::Keypoint>& keypoints = current.features->keypoints;
  const cv::Size size = current.features->image_size;
  for (std::size_t i = 0; i < keypoints.size(); ++i) {
    const bool drop = isMovable(keypoints[i])
                          ? objects.at(keypoints[i].instance_id).dropped
                          : !moving_cells.empty() && moving_cells[cellOf(keypoints[i].pixel, size)];
    if (!drop) continue;
    report.drop[i] = 1;
    ++report.dropped;
    if (!isMovable(keypoints[i])) ++report.geometric_dropped;
  }
}

void MovingObjectDetector::forgetUnseenTracks(const std::map<int, int>& track_of_instance) {
  std::map<int, Track> seen;
  for (const auto& [instance, track] : track_of_instance) {
    if (const auto found = tracks_.find(track); found != tracks_.end()) seen.insert(*found);
  }
  tracks_ = std::move(seen);
}

MovingObjectReport MovingObjectDetector::detect(const FrameObservations* previous,
                                                const FrameObservations& current,
                                                const SE3d& T_cur_prev) {
  MovingObjectReport report;
  const std::vector<features::Keypoint>& keypoints = current.features->keypoints;
  report.drop.assign(keypoints.size(), 0);
  if (options_.mode == DynamicMode::kOff && !options_.geometric) return report;

  std::map<int, ObjectDecision> objects;  // by current instance id
  for (const features::Keypoint& keypoint : keypoints) {
    if (!isMovable(keypoint)) continue;
    ObjectDecision& object = objects[keypoint.instance_id];
    object.instance_id = keypoint.instance_id;
    object.class_id = keypoint.class_id;
    ++object.keypoints;
  }

  std::map<int, std::vector<Pair>> pairs_of;  // by current instance id
  std::set<int> on_background;                // objects paired with the previous frame's background
  std::vector<char> moving_cells;
  const bool test_objects = options_.mode == DynamicMode::kSemanticGeometric;
  SE3d T_motion = T_cur_prev;  // refined on the background where possible
  if (previous && (test_objects || options_.geometric)) {
    const std::vector<Pair> background =
        matchPairs(*previous, current, T_cur_prev, false, false, {});
    report.background_pairs = static_cast<int>(background.size());
    const SE3d T = options_.refine_motion
                       ? refinedMotion(background, *previous, current, T_cur_prev)
                       : T_cur_prev;
    T_motion = T;
    const std::vector<Baseline> baselines = baselinesOf(background, *previous, current, T);
    if (options_.geometric) {
      // Background features that left the narrow search radius (fast unlabelled movers) are
      // searched again as widely as objects; only the cell test sees those pairs.
      std::vector<Pair> all = background;
      for (const Pair& pair : matchPairs(*previous, current, T_cur_prev, false, true, background)) {
        all.push_back(pair);
      }
      moving_cells = movingBackgroundCells(linksOf(all, *previous), current, T,
                                           baselines.front().thresholds, report);
    }
    std::vector<Pair> all_pairs = background;
    if (test_objects) {
      for (const Pair& pair : matchPairs(*previous, current, T_cur_prev, true, true, {}))
        pairs_of[keypoints[pair.current].instance_id].push_back(pair);
      if (options_.background_pairs_for_new_objects)
        on_background =
            addBackgroundPairsOfUnpairedObjects(*previous, current, T_cur_prev, pairs_of);
      for (const auto& [instance, pairs] : pairs_of)
        all_pairs.insert(all_pairs.end(), pairs.begin(), pairs.end());
      testObjects(pairs_of, *previous, current, baselines, objects);
    }
    rememberChains(all_pairs, *previous, current, T);
  } else {
    chains_.clear();
    earlier_.clear();
  }

  std::vector<int> instances;
  for (const auto& [instance, object] : objects)
    instances.push_back(instance);
  std::map<int, int> track_of_instance;
  if (options_.mode == DynamicMode::kSemanticGeometric) {
    track_of_instance = associateTracks(pairs_of, instances, previous, current, T_motion);
  }
  for (auto& [instance, object] : objects) {
    if (options_.mode == DynamicMode::kSemantic) {
      object.decision = ObjectState::kMoving;
      object.dropped = true;
    } else {
      object.track_id = track_of_instance.at(instance);
      const int needed =
          std::max(std::min(options_.min_votes, object.tested),
                   static_cast<int>(std::ceil(options_.moving_vote_share * object.tested)));
      const bool tested_moving = object.tested > 0 && object.votes >= needed;
      // Pairs with the background can only clear an object: the background they come from was
      // partly where the object now stands, and it may just have come out from behind it.
      if (tested_moving && on_background.count(instance)) {
        applyTrackState(object);
      } else {
        applyHysteresis(object, tested_moving);
      }
    }
    if (object.decision == ObjectState::kMoving) {
      // The map points of its keypoints in the previous frame go; those of keypoints labelled
      // background there stay (its pairs with them may be the background it now hides).
      for (const Pair& pair : pairs_of[instance]) {
        if (isMovable(previous->features->keypoints[static_cast<std::size_t>(pair.previous)]))
          report.moving_previous_keypoints.push_back(pair.previous);
      }
    }
    report.objects.push_back(object);
  }
  forgetUnseenTracks(track_of_instance);
  track_of_previous_instance_ = std::move(track_of_instance);

  dropKeypoints(objects, moving_cells, current, report);
  std::sort(report.moving_previous_keypoints.begin(), report.moving_previous_keypoints.end());
  return report;
}

}  // namespace superdyna::dynamic
