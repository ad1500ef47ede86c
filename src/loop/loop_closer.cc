#include "superdyna/loop/loop_closer.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <iterator>
#include <limits>
#include <map>
#include <set>

#include "superdyna/core/error.h"
#include "superdyna/core/geometry.h"
#include "superdyna/features/feature_set.h"
#include "superdyna/features/matcher.h"
#include "superdyna/mapping/keyframe_keypoints.h"

namespace superdyna::loop {

void LoopClosingOptions::validate() const {
  database.validate();
  ransac.validate();
  pose_graph.validate();
  if (!(min_time_gap_s >= 0.0)) throw OptionError("loop.min_time_gap_s", "must be >= 0");
  if (!(min_score >= 0.0 && min_score <= 1.0))
    throw OptionError("loop.min_score", "must be in [0, 1]");
  if (group_keyframes < 0) throw OptionError("loop.group_keyframes", "must be >= 0");
  if (consistency < 1) throw OptionError("loop.consistency", "must be >= 1");
  if (max_candidates < 1) throw OptionError("loop.max_candidates", "must be >= 1");
  if (keyframes_between_loops < 0) {
    throw OptionError("loop.keyframes_between_loops", "must be >= 0");
  }
  if (match_max_hamming < 0) throw OptionError("loop.match_max_hamming", "must be >= 0");
  if (!(match_max_l2 >= 0.0)) throw OptionError("loop.match_max_l2", "must be >= 0");
  if (!(match_ratio > 0.0 && match_ratio <= 1.0)) {
    throw OptionError("loop.match_ratio", "must be in (0, 1]");
  }
  if (!(ransac_chi2 > 0.0)) throw OptionError("loop.ransac_chi2", "must be > 0");
  if (!(guided_radius_px > 0.0)) throw OptionError("loop.guided_radius_px", "must be > 0");
  if (min_inliers < 3) throw OptionError("loop.min_inliers", "must be >= 3");
  if (!(max_roll_pitch_deg > 0.0)) throw OptionError("loop.max_roll_pitch_deg", "must be > 0");
  if (!(max_correction_deg > 0.0)) throw OptionError("loop.max_correction_deg", "must be > 0");
  if (!(max_correction_path_share > 0.0)) {
    throw OptionError("loop.max_correction_path_share", "must be > 0");
  }
  if (!(min_correction_m >= 0.0)) throw OptionError("loop.min_correction_m", "must be >= 0");
  if (strong_covisibility < 1) throw OptionError("loop.strong_covisibility", "must be >= 1");
}

struct LoopCloser::Candidate {
  map::KeyFrameId id = map::kNoKeyFrame;  ///< The best-scoring keyframe of the group.
  std::vector<map::KeyFrameId> group;     ///< Sorted.
  double group_score = 0.0;
  std::shared_ptr<map::Map> other;  ///< A merge candidate's atlas map (null: the query's map).
};

namespace {

using Clock = std::chrono::steady_clock;

/// The map points of the loop group that verification matches against.
struct LoopPoints {
  std::vector<map::MapPointId> ids;
  std::vector<Eigen::Vector3d> p_w;
  features::FeatureSet features;  ///< Descriptors (keypoints: octave and angle of no use here).
};

/// The query keyframe's background keypoints with a 3D position in its camera.
struct QueryPoints {
  std::vector<int> index;  ///< Keypoint index in the keyframe.
  std::vector<Eigen::Vector3d> p_c;
  features::FeatureSet features;
};

features::DescriptorType descriptorType(const cv::Mat& descriptors) {
  return descriptors.type() == CV_32FC1 ? features::DescriptorType::kFloat
                                        : features::DescriptorType::kBinary;
}

std::vector<map::KeyFrameId> sortedGroup(map::KeyFrameId id, std::vector<map::KeyFrameId> others) {
  others.push_back(id);
  std::sort(others.begin(), others.end());
  others.erase(std::unique(others.begin(), others.end()), others.end());
  return others;
}

bool intersects(const std::vector<map::KeyFrameId>& a, const std::vector<map::KeyFrameId>& b) {
  auto i = a.begin();
  auto j = b.begin();
  while (i != a.end() && j != b.end()) {
    if (*i == *j) return true;
    if (*i < *j) {
      ++i;
    } else {
      ++j;
    }
  }
  return false;
}

LoopPoints loopPoints(const map::Map& map, const std::vector<map::KeyFrameId>& group,
                      const map::KeyFrame& query) {
  std::set<map::MapPointId> ids;
  for (const map::KeyFrameId id : group) {
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
      for (const map::MapPointId p : kf.map_points)
        if (p != map::kNoMapPoint) ids.insert(p);
    });
  }
  LoopPoints points;
  points.features.descriptor_type = descriptorType(query.descriptors);
  std::vector<cv::Mat> rows;
  for (const map::MapPointId id : ids) {
    map.readMapPoint(id, [&](const map::MapPoint& p) {
      if (p.bad || p.descriptor.empty() || p.class_id != features::kClassBackground ||
          p.descriptor.type() != query.descriptors.type() ||
          p.descriptor.cols != query.descriptors.cols || p.observations.contains(query.id)) {
        return;
      }
      points.ids.push_back(id);
      points.p_w.push_back(p.p_w);
      rows.push_back(p.descriptor);
      points.features.keypoints.emplace_back();
    });
  }
  if (!rows.empty()) cv::vconcat(rows, points.features.descriptors);
  return points;
}

QueryPoints queryPoints(const map::Map& map, const map::KeyFrame& query, const SE3d& T_c_w) {
  QueryPoints points;
  points.features.descriptor_type = descriptorType(query.descriptors);
  std::vector<int> rows;
  for (std::size_t i = 0; i < query.keypoints.size(); ++i) {
    const map::KeyFrameKeypoint& k = query.keypoints[i];
    if (k.class_id != features::kClassBackground || !k.valid() || k.camera != 0) continue;
    std::optional<Eigen::Vector3d> p_c;
    if (k.hasStereo()) {
      p_c = k.depth_m * Eigen::Vector3d(k.normalized.x(), k.normalized.y(), 1.0);
    } else if (query.map_points[i] != map::kNoMapPoint) {
      if (const auto p_w = map.mapPointPosition(query.map_points[i])) p_c = T_c_w * *p_w;
    }
    if (!p_c || !(p_c->z() > 0.0)) continue;
    points.index.push_back(static_cast<int>(i));
    points.p_c.push_back(*p_c);
    points.features.keypoints.push_back(mapping::asFeatureKeypoint(k));
    rows.push_back(static_cast<int>(i));
  }
  points.features.descriptors =
      cv::Mat(static_cast<int>(rows.size()), query.descriptors.cols, query.descriptors.type());
  for (std::size_t r = 0; r < rows.size(); ++r)
    query.descriptors.row(rows[r]).copyTo(points.features.descriptors.row(static_cast<int>(r)));
  return points;
}

optim::PoseObservation observationOf(const map::KeyFrameKeypoint& k, const Eigen::Vector3d& p_w) {
  optim::PoseObservation o;
  o.p_w = p_w;
  o.normalized = k.normalized;  // left camera only: the rig need not be rectified
  o.octave = k.octave;
  return o;
}

/// Angle [deg] by which a rotation tilts the world z axis (its roll and pitch).
double tiltDegrees(const Eigen::Matrix3d& R) {
  const double c = std::clamp((R * Eigen::Vector3d::UnitZ()).z(), -1.0, 1.0);
  return std::acos(c) * 180.0 / M_PI;
}

/// The correction that moves a keyframe from T_old to T_new, with a scale change (Sim(3));
/// with scale 1 exactly the rigid T_new * T_old^-1.
map::KeyFrameCorrection correctionBetween(const SE3d& T_old, const SE3d& T_new, double scale) {
  map::KeyFrameCorrection c;
  c.C = T_new * T_old.inverse();
  c.scale = scale;
  if (scale != 1.0) c.C.t = T_new.t - scale * (c.C.q * T_old.t);
  return c;
}

/// Median ratio of the loop points' depths seen from the verified query camera to the query's
/// own points' depths over the same keypoints: the loop's scale in a monocular map; `fallback`
/// with fewer than 10 such pairs.
double medianDepthRatio(const std::vector<std::pair<int, Eigen::Vector3d>>& loop_in_camera,
                        const QueryPoints& mine, double fallback) {
  std::map<int, double> own_depth;
  for (std::size_t r = 0; r < mine.index.size(); ++r)
    own_depth[mine.index[r]] = mine.p_c[r].norm();
  std::vector<double> ratios;
  for (const auto& [keypoint, p_c] : loop_in_camera) {
    const auto own = own_depth.find(keypoint);
    if (own != own_depth.end() && own->second > 0.0) ratios.push_back(p_c.norm() / own->second);
  }
  if (ratios.size() < 10) return fallback;
  const auto middle = ratios.begin() + static_cast<std::ptrdiff_t>(ratios.size() / 2);
  std::nth_element(ratios.begin(), middle, ratios.end());
  return *middle;
}

}  // namespace

SE3d loopError(const LoopClosure& loop, const SE3d& T_match_query_true, const SE3d& T_b_c) {
  const SE3d truth = T_b_c.inverse() * T_match_query_true * T_b_c;
  SE3d estimate = T_b_c.inverse() * loop.T_match_query * T_b_c;
  if (loop.scale != 1.0 && estimate.t.norm() > 0.0)
    estimate.t *= truth.t.norm() / estimate.t.norm();
  return truth.inverse() * estimate;
}

LoopCloser::LoopCloser(const LoopClosingOptions& options, const CameraModel& camera0,
                       const optim::ReprojectionCamera& camera,
                       const mapping::PointFusionOptions& fusion,
                       const optim::PoseOptimizerOptions& pose, bool monocular)
    : options_(options),
      monocular_(monocular),
      camera0_(camera0),
      camera_(camera),
      fuser_(fusion, camera),
      pose_optimizer_(pose),
      database_(options.database) {
  options_.validate();
  camera_.validate();
}

void LoopCloser::reset() {
  {
    const std::lock_guard lock(database_mutex_);
    if (atlas_ && atlas_->numMaps() > 0) {
      // The atlas maps never change: their keyframes go into the graph index now.
      database_.settle(std::numeric_limits<TimeNs>::max(), atlas_->keyFrameIds());
    } else {
      database_.clear();
    }
  }
  groups_.clear();
  // Kept: a merge brings their keyframes back into a map (edges apply where both ends are).
  if (!atlas_) loop_edges_.clear();
  keyframes_since_loop_ = 0;
  had_loop_ = false;
  indexed_earlier_ = false;
}

LoopStep LoopCloser::processKeyFrame(map::Map& map, map::KeyFrameId keyframe, bool inertial) {
  LoopStep step = findLoop(map, keyframe, inertial);
  if (!step.found) return step;
  const auto start = Clock::now();
  step.closure = closeLoop(map, *step.found, inertial);
  step.correction_ms = millisecondsSince(start);
  step.found.reset();
  return step;
}

LoopStep LoopCloser::findLoop(const map::Map& map, map::KeyFrameId keyframe, bool inertial) {
  LoopStep step;
  if (!options_.enabled) return step;
  const std::optional<map::KeyFrame> query = map.keyFrame(keyframe);
  if (!query || query->descriptors.empty()) return step;
  auto start = Clock::now();
  if (!indexed_earlier_) indexEarlierKeyFrames(map, keyframe);
  settleDatabase(map, query->t_ns);
  ++keyframes_since_loop_;
  const bool resting = had_loop_ && keyframes_since_loop_ <= options_.keyframes_between_loops;
  std::vector<Candidate> candidates = detect(map, *query);
  if (resting) candidates.clear();
  const std::vector<Candidate> consistent = consistentCandidates(map, candidates);
  step.detection_ms = millisecondsSince(start);
  start = Clock::now();
  for (const Candidate& candidate : consistent) {
    if (step.candidates >= options_.max_candidates) break;
    ++step.candidates;
    Rejection rejection = Rejection::kTooFewMatches;
    const map::Map& match_map = candidate.other ? *candidate.other : map;
    step.found = verify(map, match_map, *query, candidate.id, inertial, rejection);
    if (step.found) {
      step.found->other = candidate.other;
      break;
    }
    ++step.rejected[static_cast<int>(rejection)];
  }
  step.verification_ms = millisecondsSince(start);
  if (!step.found) return step;
  groups_.clear();
  keyframes_since_loop_ = 0;
  had_loop_ = true;
  return step;
}

std::optional<LoopClosure> LoopCloser::closeLoop(map::Map& map, const VerifiedLoop& loop,
                                                 bool inertial) {
  LoopClosure closure;
  closure.query = loop.query;
  closure.match = loop.match;
  closure.inliers = loop.inliers;
  if (loop.other) {
    if (!mergeMap(map, loop, closure)) return std::nullopt;
    return closure;
  }
  const bool found = map.readKeyFrame(loop.query, [&](const map::KeyFrame& kf) {
    closure.query_t_ns = kf.t_ns;
    closure.correction = loop.T_w_b_query * kf.T_w_b.inverse();
    closure.scale = loop.scale;
  }) && map.readKeyFrame(loop.match, [&](const map::KeyFrame& kf) {
    closure.match_t_ns = kf.t_ns;
  });
  if (!found || !correct(map, loop, inertial)) return std::nullopt;
  if (options_.fuse) fuseLoop(map, loop);
  const std::optional<SE3d> T_w_match = map.keyFramePose(loop.match);
  const std::optional<SE3d> T_w_query = map.keyFramePose(loop.query);
  if (T_w_match && T_w_query) closure.T_match_query = T_w_match->inverse() * *T_w_query;
  return closure;
}

void LoopCloser::indexEarlierKeyFrames(const map::Map& map, map::KeyFrameId first) {
  indexed_earlier_ = true;
  for (const map::KeyFrameId id : map.keyFrameIds()) {
    if (id >= first) continue;
    cv::Mat rows;
    TimeNs t_ns = 0;
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
      rows = placeDescriptorRows(kf, options_.database.max_descriptors);
      t_ns = kf.t_ns;
    });
    const std::lock_guard lock(database_mutex_);
    database_.add(id, t_ns, rows);
  }
}

void LoopCloser::settleDatabase(const map::Map& map, TimeNs now_ns) {
  std::vector<map::KeyFrameId> alive = map.keyFrameIds();
  if (atlas_) {
    const std::vector<map::KeyFrameId> kept = atlas_->keyFrameIds();
    alive.insert(alive.end(), kept.begin(), kept.end());
    std::sort(alive.begin(), alive.end());
  }
  const std::lock_guard lock(database_mutex_);
  database_.settle(now_ns, alive);
}

std::vector<PlaceScore> LoopCloser::recognize(const cv::Mat& rows, int count) const {
  if (!options_.enabled || rows.empty()) return {};
  std::vector<PlaceScore> scores;
  {
    const std::lock_guard lock(database_mutex_);
    if (database_.numKeyFrames() == 0) return {};
    scores = database_.query(rows);
  }
  if (static_cast<int>(scores.size()) > count) scores.resize(static_cast<std::size_t>(count));
  return scores;
}

std::vector<LoopCloser::Candidate> LoopCloser::detect(const map::Map& map,
                                                      const map::KeyFrame& query) {
  const cv::Mat rows = placeDescriptorRows(query, options_.database.max_descriptors);
  std::vector<PlaceScore> scores;
  {
    const std::lock_guard lock(database_mutex_);
    scores = database_.query(rows);
    database_.add(query.id, query.t_ns, rows);
  }
  std::map<map::KeyFrameId, double> score_of;
  for (const PlaceScore& s : scores)
    score_of[s.id] = s.score;
  std::set<map::KeyFrameId> excluded{query.id};
  for (const map::CovisibleKeyFrame& c : map.covisibleKeyFrames(query.id))
    excluded.insert(c.id);
  // The bar: the least similar of the best covisible keyframes (ORB-SLAM's minScore).
  double bar = options_.min_score;
  const std::vector<map::KeyFrameId> best =
      map.bestCovisibleKeyFrames(query.id, options_.group_keyframes);
  if (!best.empty()) {
    double least = 1.0;
    for (const map::KeyFrameId id : best) {
      const auto it = score_of.find(id);
      least = std::min(least, it == score_of.end() ? 0.0 : it->second);
    }
    bar = std::max(bar, least);
  }
  const TimeNs latest = query.t_ns - secondsToNs(options_.min_time_gap_s);
  std::map<map::KeyFrameId, double> passed;
  for (const PlaceScore& s : scores) {
    if (s.score < bar || excluded.contains(s.id)) continue;
    TimeNs t_ns = 0;
    if (!map.readKeyFrame(s.id, [&](const map::KeyFrame& kf) { t_ns = kf.t_ns; })) continue;
    if (t_ns > latest) continue;
    passed[s.id] = s.score;
  }
  std::vector<Candidate> candidates = groupCandidates(map, passed);
  if (atlas_) {
    std::vector<Candidate> merges = mergeCandidates(scores, bar);
    candidates.insert(candidates.end(), std::make_move_iterator(merges.begin()),
                      std::make_move_iterator(merges.end()));
  }
  return candidates;
}

std::vector<LoopCloser::Candidate> LoopCloser::mergeCandidates(
    const std::vector<PlaceScore>& scores, double bar) const {
  // Per atlas map, in the order of their best scores (deterministic, unlike their addresses).
  std::vector<std::pair<std::shared_ptr<map::Map>, std::map<map::KeyFrameId, double>>> passed;
  for (const PlaceScore& s : scores) {
    if (s.score < bar) continue;
    std::shared_ptr<map::Map> other = atlas_->mapOf(s.id);
    if (!other) continue;
    auto it = std::find_if(passed.begin(), passed.end(),
                           [&](const auto& entry) { return entry.first == other; });
    if (it == passed.end()) it = passed.insert(passed.end(), {std::move(other), {}});
    it->second[s.id] = s.score;
  }
  std::vector<Candidate> candidates;
  for (const auto& [other, in_other] : passed) {
    for (Candidate& candidate : groupCandidates(*other, in_other)) {
      candidate.other = other;
      candidates.push_back(std::move(candidate));
    }
  }
  return candidates;
}

std::vector<LoopCloser::Candidate> LoopCloser::groupCandidates(
    const map::Map& map, const std::map<map::KeyFrameId, double>& passed) const {
  std::vector<Candidate> groups;
  double best_score = 0.0;
  for (const auto& [id, score] : passed) {
    Candidate group;
    group.id = id;
    group.group_score = score;
    double best_member = score;
    const std::vector<map::KeyFrameId> neighbours =
        map.bestCovisibleKeyFrames(id, options_.group_keyframes);
    for (const map::KeyFrameId other : neighbours) {
      const auto it = passed.find(other);
      if (it == passed.end()) continue;
      group.group_score += it->second;
      if (it->second > best_member) {
        best_member = it->second;
        group.id = other;
      }
    }
    group.group = sortedGroup(id, neighbours);
    best_score = std::max(best_score, group.group_score);
    groups.push_back(std::move(group));
  }
  std::vector<Candidate> kept;
  for (Candidate& group : groups)
    if (group.group_score >= 0.75 * best_score) kept.push_back(std::move(group));
  std::stable_sort(kept.begin(), kept.end(), [](const Candidate& a, const Candidate& b) {
    return a.group_score > b.group_score;
  });
  return kept;
}

std::vector<LoopCloser::Candidate> LoopCloser::consistentCandidates(
    const map::Map& map, const std::vector<Candidate>& groups) {
  (void)map;
  std::vector<Group> current;
  std::vector<Candidate> consistent;
  std::set<map::KeyFrameId> chosen;
  for (const Candidate& candidate : groups) {
    int consistency = 1;
    for (const Group& previous : groups_)
      if (intersects(previous.members, candidate.group))
        consistency = std::max(consistency, previous.consistency + 1);
    current.push_back({candidate.group, consistency});
    if (consistency >= options_.consistency && chosen.insert(candidate.id).second) {
      consistent.push_back(candidate);
    }
  }
  groups_ = std::move(current);
  return consistent;
}

std::optional<VerifiedLoop> LoopCloser::verify(const map::Map& map, const map::Map& match_map,
                                               const map::KeyFrame& query,
                                               map::KeyFrameId candidate, bool inertial,
                                               Rejection& rejection) const {
  const map::Map::ReadLock reading = map.readLock();  // one state of the loop's points
  VerifiedLoop out;
  out.query = query.id;
  out.match = candidate;
  out.loop_group =
      sortedGroup(candidate, match_map.bestCovisibleKeyFrames(candidate, options_.group_keyframes));
  const LoopPoints loop = loopPoints(match_map, out.loop_group, query);
  const SE3d T_w_c = query.T_w_b * camera_.T_b_c;
  const QueryPoints mine = queryPoints(map, query, T_w_c.inverse());
  if (static_cast<int>(loop.ids.size()) < options_.ransac.min_inliers ||
      static_cast<int>(mine.index.size()) < options_.ransac.min_inliers) {
    return std::nullopt;
  }
  features::BruteForceMatchOptions matching;
  matching.max_distance = options_.match_max_hamming;
  matching.max_l2_distance = options_.match_max_l2;
  matching.ratio = options_.match_ratio;
  const std::vector<features::Match> matches =
      features::matchBruteForce(mine.features, loop.features, matching);
  if (static_cast<int>(matches.size()) < options_.ransac.min_inliers) return std::nullopt;

  // RANSAC: the query camera in the loop's frame, p_loop_w = T * p_c.
  std::vector<Eigen::Vector3d> a, b;
  for (const features::Match& m : matches) {
    a.push_back(loop.p_w[static_cast<std::size_t>(m.train)]);
    b.push_back(mine.p_c[static_cast<std::size_t>(m.query)]);
  }
  const double focal = 0.5 * (camera_.fx + camera_.fy);
  const map::MapOptions& pyramid = map.options();
  const auto is_inlier = [&](const SE3d& T_w_c_hyp, std::size_t i) {
    const Eigen::Vector3d p_c = T_w_c_hyp.inverse() * a[i];
    if (!(p_c.z() > 0.0)) return false;
    const map::KeyFrameKeypoint& k = query.keypoints[static_cast<std::size_t>(
        mine.index[static_cast<std::size_t>(matches[i].query)])];
    const double sigma = optim::octaveSigmaPx(k.octave, 1.0, pyramid.scale_factor);
    const Eigen::Vector2d error = focal * (p_c.head<2>() / p_c.z() - k.normalized);
    return error.squaredNorm() < options_.ransac_chi2 * sigma * sigma;
  };
  rejection = Rejection::kNoTransform;
  const std::optional<RigidRansacResult> ransac =
      similarity(inertial) ? ransacSimilarity(a, b, is_inlier, options_.ransac)
                           : ransacRigid(a, b, is_inlier, options_.ransac);
  if (!ransac) return std::nullopt;
  std::vector<optim::PoseObservation> observations;
  for (std::size_t i = 0; i < matches.size(); ++i) {
    if (!ransac->inliers[i]) continue;
    const int index = mine.index[static_cast<std::size_t>(matches[i].query)];
    observations.push_back(observationOf(query.keypoints[static_cast<std::size_t>(index)], a[i]));
  }
  const std::vector<optim::ReprojectionCamera> cameras{camera_};
  const optim::PoseOptimizationResult first =
      pose_optimizer_.optimize(ransac->T_a_b * camera_.T_b_c.inverse(), cameras, observations);
  if (!first.success) return std::nullopt;

  rejection = Rejection::kTooFewInliers;
  // Guided matching: every loop point projected from the verified pose into the query keyframe.
  features::FeatureSet train;
  train.descriptor_type = descriptorType(query.descriptors);
  train.descriptors = query.descriptors;
  train.image_size = cv::Size(camera0_.width(), camera0_.height());
  for (const map::KeyFrameKeypoint& k : query.keypoints)
    train.keypoints.push_back(mapping::asFeatureKeypoint(k));
  const SE3d T_c_w = (first.T_w_b * camera_.T_b_c).inverse();
  features::FeatureSet projected;
  projected.descriptor_type = train.descriptor_type;
  std::vector<Eigen::Vector2d> predicted;
  std::vector<int> projected_point;
  std::vector<cv::Mat> rows;
  for (std::size_t k = 0; k < loop.ids.size(); ++k) {
    const Eigen::Vector3d p_c = T_c_w * loop.p_w[k];
    if (!(p_c.z() > 0.05)) continue;
    const std::optional<Eigen::Vector2d> pixel = camera0_.project(p_c);
    if (!pixel || !camera0_.isInImage(*pixel)) continue;
    predicted.push_back(*pixel);
    projected_point.push_back(static_cast<int>(k));
    rows.push_back(loop.features.descriptors.row(static_cast<int>(k)));
    projected.keypoints.emplace_back();
  }
  if (static_cast<int>(rows.size()) < options_.min_inliers) return std::nullopt;
  cv::vconcat(rows, projected.descriptors);
  features::ProjectionMatchOptions guided;
  guided.radius_px = options_.guided_radius_px;
  guided.max_distance = options_.match_max_hamming;
  guided.max_l2_distance = options_.match_max_l2;
  guided.ratio = 1.0;
  guided.check_orientation = false;
  const features::KeypointGrid grid(train.keypoints, train.image_size);
  const std::vector<features::Match> found =
      features::matchByProjection(projected, predicted, train, grid, guided);
  std::vector<std::pair<int, map::MapPointId>> pairs;
  observations.clear();
  for (const features::Match& m : found) {
    const map::KeyFrameKeypoint& k = query.keypoints[static_cast<std::size_t>(m.train)];
    if (k.class_id != features::kClassBackground || !k.valid() || k.camera != 0) continue;
    const std::size_t point =
        static_cast<std::size_t>(projected_point[static_cast<std::size_t>(m.query)]);
    pairs.emplace_back(m.train, loop.ids[point]);
    observations.push_back(observationOf(k, loop.p_w[point]));
  }
  if (static_cast<int>(observations.size()) < options_.min_inliers) return std::nullopt;
  const optim::PoseOptimizationResult final_pose =
      pose_optimizer_.optimize(first.T_w_b, cameras, observations);
  if (final_pose.num_inliers < options_.min_inliers) return std::nullopt;
  const SE3d T_c_w_final = (final_pose.T_w_b * camera_.T_b_c).inverse();
  std::vector<std::pair<int, Eigen::Vector3d>> loop_in_camera;
  for (std::size_t i = 0; i < pairs.size(); ++i) {
    if (!final_pose.inliers[i]) continue;
    out.matches.push_back(pairs[i]);
    loop_in_camera.emplace_back(pairs[i].first, T_c_w_final * observations[i].p_w);
  }
  out.inliers = final_pose.num_inliers;
  out.T_w_b_query = final_pose.T_w_b;
  if (similarity(inertial)) out.scale = medianDepthRatio(loop_in_camera, mine, ransac->scale);
  if (inertial) {
    // Gravity observes roll and pitch: a loop that changes them is wrong; keep yaw and position.
    const Eigen::Matrix3d R_correction =
        out.T_w_b_query.rotation() * query.T_w_b.rotation().transpose();
    rejection = Rejection::kTilted;
    if (tiltDegrees(R_correction) > options_.max_roll_pitch_deg) return std::nullopt;
    out.T_w_b_query =
        SE3d(yawRotation(yawOf(R_correction)) * query.T_w_b.rotation(), out.T_w_b_query.t);
  }
  rejection = Rejection::kBeyondDrift;
  const bool merge = &match_map != &map;  // the frames of two maps are unrelated: no drift bound
  if (!merge && !withinDrift(map, query, candidate, out.T_w_b_query, inertial)) return std::nullopt;
  return out;
}

bool LoopCloser::withinDrift(const map::Map& map, const map::KeyFrame& query, map::KeyFrameId match,
                             const SE3d& T_w_b_new, bool inertial) const {
  const Eigen::Matrix3d R_correction = T_w_b_new.rotation() * query.T_w_b.rotation().transpose();
  if (rotationAngle(R_correction) * 180.0 / M_PI > options_.max_correction_deg) return false;
  std::optional<TimeNs> t_match;
  map.readKeyFrame(match, [&](const map::KeyFrame& kf) { t_match = kf.t_ns; });
  if (!t_match) return false;
  std::vector<std::pair<TimeNs, Eigen::Vector3d>> positions;
  for (const map::KeyFrameId id : map.keyFrameIds()) {
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
      if (kf.t_ns >= *t_match && kf.t_ns <= query.t_ns) positions.emplace_back(kf.t_ns, kf.T_w_b.t);
    });
  }
  std::sort(positions.begin(), positions.end(),
            [](const auto& a, const auto& b) { return a.first < b.first; });
  double path = 0.0;
  for (std::size_t i = 1; i < positions.size(); ++i)
    path += (positions[i].second - positions[i - 1].second).norm();
  const double floor = similarity(inertial) ? 0.0 : options_.min_correction_m;
  return (T_w_b_new.t - query.T_w_b.t).norm() <= options_.max_correction_path_share * path + floor;
}

bool LoopCloser::correct(map::Map& map, const VerifiedLoop& loop, bool inertial) {
  struct Snapshot {
    SE3d T_w_b;
    map::KeyFrameId previous = map::kNoKeyFrame;
    TimeNs t_ns = 0;
  };
  std::map<map::KeyFrameId, Snapshot> nodes;
  std::vector<PoseGraphEdge> edges;
  {
    const map::Map::ReadLock reading = map.readLock();
    for (const map::KeyFrameId id : map.keyFrameIds()) {
      map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
        nodes[id] = {kf.T_w_b, kf.previous, kf.t_ns};
      });
    }
    for (const auto& [id, node] : nodes) {
      const auto previous = nodes.find(node.previous);
      if (previous != nodes.end())
        edges.push_back(edgeBetween(node.previous, previous->second.T_w_b, id, node.T_w_b));
      for (const map::CovisibleKeyFrame& c :
           map.covisibleKeyFrames(id, options_.strong_covisibility)) {
        const auto other = nodes.find(c.id);
        if (c.id > id && c.id != node.previous && other != nodes.end() &&
            other->second.previous != id) {
          edges.push_back(edgeBetween(id, node.T_w_b, c.id, other->second.T_w_b));
        }
      }
    }
  }
  if (!nodes.contains(loop.query) || !nodes.contains(loop.match)) return false;
  for (const PoseGraphEdge& edge : loop_edges_)
    if (nodes.contains(edge.from) && nodes.contains(edge.to)) edges.push_back(edge);
  const map::KeyFrameCorrection C_query =
      correctionBetween(nodes.at(loop.query).T_w_b, loop.T_w_b_query, loop.scale);
  std::map<map::KeyFrameId, SE3d> initial;
  std::map<map::KeyFrameId, double> initial_scale;
  for (const auto& [id, node] : nodes)
    initial[id] = node.T_w_b;
  const std::vector<map::KeyFrameId> current =
      sortedGroup(loop.query, map.bestCovisibleKeyFrames(loop.query, options_.group_keyframes));
  for (const map::KeyFrameId id : current) {
    if (!nodes.contains(id)) continue;
    initial[id] = C_query.apply(nodes.at(id).T_w_b);
    initial_scale[id] = loop.scale;
  }
  for (const map::KeyFrameId k : current) {
    if (!nodes.contains(k)) continue;
    for (const map::KeyFrameId l : loop.loop_group) {
      if (!nodes.contains(l) || std::binary_search(current.begin(), current.end(), l)) continue;
      if (k != loop.query && l != loop.match)
        continue;  // the query to the loop group, its group to the match
      PoseGraphEdge edge = edgeBetween(l, nodes.at(l).T_w_b, 1.0, k, initial.at(k), loop.scale);
      edges.push_back(edge);
      edge.log_scale = 0.0;  // after this correction both frames have the map's one scale
      loop_edges_.push_back(edge);
    }
  }
  PoseGraphOptions graph = options_.pose_graph;
  graph.four_dof = inertial;
  graph.seven_dof = similarity(inertial);
  const PoseGraphResult result =
      optimizePoseGraph(initial, edges, {loop.match}, graph, initial_scale);

  const map::Map::UpdateLock update = map.updateLock();  // the correction is one map update
  std::map<map::KeyFrameId, map::KeyFrameCorrection> correction;
  for (const auto& [id, node] : nodes)
    correction[id] = correctionBetween(node.T_w_b, result.T_w_b.at(id), result.scale.at(id));
  // Keyframes inserted meanwhile follow the newest one.
  const map::KeyFrameCorrection newest = correction.rbegin()->second;
  map::MapCorrection record;
  for (const map::KeyFrameId id : map.keyFrameIds()) {
    const auto it = correction.find(id);
    map::KeyFrameCorrection C = it == correction.end() ? newest : it->second;
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) { C.t_ns = kf.t_ns; });
    record.keyframes.push_back(C);
    const std::optional<map::KeyFrame> kf = map.keyFrame(id);
    map.setKeyFramePose(id, C.apply(kf->T_w_b));
    if (inertial) map.rotateKeyFrameVelocity(id, C.C.rotation());
    correction[id] = C;
  }
  for (const map::MapPointId id : map.mapPointIds()) {
    std::optional<std::pair<map::KeyFrameId, Eigen::Vector3d>> reference;
    map.readMapPoint(id, [&](const map::MapPoint& p) {
      if (!p.observations.empty()) reference.emplace(p.observations.begin()->first, p.p_w);
    });
    if (!reference) continue;
    const auto it = correction.find(reference->first);
    if (it == correction.end()) continue;
    map.setMapPointPosition(id, it->second.apply(reference->second));
    map.updateNormalAndDistances(id);
  }
  std::stable_sort(record.keyframes.begin(), record.keyframes.end(),
                   [](const auto& x, const auto& y) { return x.t_ns < y.t_ns; });
  map.recordCorrection(std::move(record));
  return true;
}

void LoopCloser::fuseLoop(map::Map& map, const VerifiedLoop& loop) const {
  {
    const map::Map::UpdateLock update = map.updateLock();  // the loop's points, one map update
    for (const auto& [index, point] : loop.matches) {
      std::optional<map::KeyFrame> now = map.keyFrame(loop.query);
      if (!now) return;
      const map::MapPointId own = now->map_points[static_cast<std::size_t>(index)];
      if (own == point || !map.hasMapPoint(point)) continue;
      bool observed_elsewhere = false;
      map.readMapPoint(point, [&](const map::MapPoint& p) {
        observed_elsewhere = p.bad || p.observations.contains(loop.query);
      });
      if (observed_elsewhere) continue;
      if (own != map::kNoMapPoint) {
        map.replaceMapPoint(own, point);
      } else {
        map.addObservation(point, loop.query, index);
      }
      map.updateNormalAndDistances(point);
    }
  }
  std::vector<map::KeyFrameId> group =
      sortedGroup(loop.query, map.bestCovisibleKeyFrames(loop.query, options_.group_keyframes));
  for (const map::KeyFrameId id : group)
    fuser_.fuse(map, id);
}

bool LoopCloser::mergeMap(map::Map& map, const VerifiedLoop& loop, LoopClosure& closure) {
  const std::optional<map::KeyFrame> query = map.keyFrame(loop.query);
  if (!atlas_ || !query) return false;
  const std::shared_ptr<map::Map> other = atlas_->take(loop.other.get());
  if (!other) return false;
  // The similarity from the atlas map's frame into this one that takes the query camera's
  // verified pose there onto its pose here (a length there is loop.scale times one here).
  const SE3d T_here_c = query->T_w_b * camera_.T_b_c;
  const SE3d T_there_c = loop.T_w_b_query * camera_.T_b_c;
  const double scale = 1.0 / loop.scale;
  const Eigen::Matrix3d R = T_here_c.rotation() * T_there_c.rotation().transpose();
  const Sim3d S_here_there(scale, R, T_here_c.t - scale * (R * T_there_c.t));
  other->transformWorld(S_here_there);
  {
    const map::Map::UpdateLock update = map.updateLock();  // the merge is one map update
    map.absorb(*other);
  }
  closure.merge = true;
  closure.query_t_ns = query->t_ns;
  map.readKeyFrame(loop.match, [&](const map::KeyFrame& kf) { closure.match_t_ns = kf.t_ns; });
  closure.correction = SE3d(Eigen::Quaterniond(R), S_here_there.t);
  closure.scale = scale;
  if (options_.fuse) fuseLoop(map, loop);
  const std::optional<SE3d> T_w_match = map.keyFramePose(loop.match);
  const std::optional<SE3d> T_w_query = map.keyFramePose(loop.query);
  if (T_w_match && T_w_query) {
    closure.T_match_query = T_w_match->inverse() * *T_w_query;
    // Later pose graphs keep the two parts where the merge put them.
    loop_edges_.push_back(edgeBetween(loop.match, *T_w_match, loop.query, *T_w_query));
  }
  return true;
}

}  // namespace superdyna::loop
