#include "superdyna/tracking/tracker.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <limits>
#include <set>
#include <utility>

#include "superdyna/core/error.h"
#include "superdyna/mapping/keyframe_keypoints.h"
#include "superdyna/mapping/map_inertial_alignment.h"

namespace superdyna::tracking {

namespace {

using Clock = std::chrono::steady_clock;

/// The feature-side view of a keyframe's keypoint (position, orientation, octave, class) for
/// matching against a frame's keypoints.
features::ProjectionMatchOptions withRadius(features::ProjectionMatchOptions options,
                                            double radius_px) {
  options.radius_px = radius_px;
  return options;
}

}  // namespace

void TrackerOptions::validate() const {
  projection.validate();
  pose.validate();
  dynamic.validate();
  if (!(wide_radius_px > 0.0)) throw OptionError("tracker.wide_radius_px", "must be > 0");
  if (min_projection_matches < 0) {
    throw OptionError("tracker.min_projection_matches", "must be >= 0");
  }
  if (!(refine_radius_px >= 0.0)) throw OptionError("tracker.refine_radius_px", "must be >= 0");
  if (min_inliers < 3) throw OptionError("tracker.min_inliers", "must be >= 3");
  if (local_keyframes < 0) throw OptionError("tracker.local_keyframes", "must be >= 0");
  if (!(keyframe_tracked_ratio > 0.0 && keyframe_tracked_ratio <= 1.0)) {
    throw OptionError("tracker.keyframe_tracked_ratio", "must be in (0, 1]");
  }
  if (!(keyframe_max_interval_s > 0.0)) {
    throw OptionError("tracker.keyframe_max_interval_s", "must be > 0");
  }
  if (keyframe_min_tracked < 0) throw OptionError("tracker.keyframe_min_tracked", "must be >= 0");
  if (keyframe_min_stereo < 0) throw OptionError("tracker.keyframe_min_stereo", "must be >= 0");
  if (!(keyframe_min_interval_s >= 0.0)) {
    throw OptionError("tracker.keyframe_min_interval_s", "must be >= 0");
  }
  if (keyframe_weak_inliers < 0) {
    throw OptionError("tracker.keyframe_weak_inliers", "must be >= 0");
  }
  if (!(close_depth_baselines > 0.0)) {
    throw OptionError("tracker.close_depth_baselines", "must be > 0");
  }
  if (min_new_points < 0) throw OptionError("tracker.min_new_points", "must be >= 0");
  if (!(imu_rotation_prior_sigma_deg >= 0.0)) {
    throw OptionError("tracker.imu_rotation_prior_sigma_deg", "must be >= 0");
  }
  mono_init.validate();
  imu_prior.validate();
  if (!(imu_bridge_s >= 0.0)) throw OptionError("tracker.imu_bridge_s", "must be >= 0");
  if (!(relocalization_s >= 0.0)) throw OptionError("tracker.relocalization_s", "must be >= 0");
  if (relocalization_candidates < 1) {
    throw OptionError("tracker.relocalization_candidates", "must be >= 1");
  }
  if (!(imu_max_gap_s > 0.0)) throw OptionError("tracker.imu_max_gap_s", "must be > 0");
  reference_matching.validate();
  if (!(imu_min_keyframe_interval_s >= 0.0)) {
    throw OptionError("tracker.imu_min_keyframe_interval_s", "must be >= 0");
  }
}

const char* toString(TrackingState state) {
  switch (state) {
    case TrackingState::kTracking:
      return "tracking";
    case TrackingState::kInitialized:
      return "initialized";
    case TrackingState::kLost:
      return "lost";
    case TrackingState::kInitializing:
      return "initializing";
    case TrackingState::kRecentlyLost:
      return "recently-lost";
    case TrackingState::kLocalizing:
      return "localizing";
  }
  return "?";
}

namespace {

std::vector<optim::ReprojectionCamera> rigCameras(
    const sensors::CameraCalibration& cam0, const std::optional<sensors::CameraCalibration>& cam1) {
  std::vector<optim::ReprojectionCamera> cameras{
      optim::ReprojectionCamera::from(cam0.cameraModel(), cam0.T_b_c)};
  if (cam1) cameras.push_back(optim::ReprojectionCamera::from(cam1->cameraModel(), cam1->T_b_c));
  return cameras;
}

/// The keyframe's time, pose, velocity and biases (nothing else: no keypoints or descriptors).
map::KeyFrame inertialStateOf(const map::Map& map, map::KeyFrameId id) {
  map::KeyFrame state;
  map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
    state.t_ns = kf.t_ns;
    state.T_w_b = kf.T_w_b;
    state.v_w = kf.v_w;
    state.bg = kf.bg;
    state.ba = kf.ba;
  });
  return state;
}

}  // namespace

Tracker::Tracker(const TrackerOptions& options, const PyramidInfo& pyramid,
                 const mapping::LocalMapperOptions& mapping, const sensors::CameraCalibration& cam0,
                 const std::optional<sensors::CameraCalibration>& cam1,
                 const std::optional<sensors::ImuCalibration>& imu)
    : options_(options),
      pyramid_(pyramid),
      camera0_(cam0.cameraModel()),
      T_b_c0_(cam0.T_b_c),
      pose_optimizer_(options.pose),
      cameras_(rigCameras(cam0, cam1)),
      imu_(options.use_imu ? imu : std::nullopt),
      baseline_m_(optim::stereoBaseline(cameras_)),
      mapper_(mapping, cameras_, imu_),
      moving_detector_(options.dynamic, camera0_, pyramid.scale_factor) {
  options_.validate();
  map_ = newMap();
  if (isMonocular()) {
    MonoInitializerOptions mono = options_.mono_init;
    mono.sigma0_px = mapping.sigma0_px;
    mono.scale_factor = pyramid_.scale_factor;
    mono_initializer_.emplace(mono, 0.5 * (cam0.fx + cam0.fy));
  }
}

Tracker::Prediction Tracker::predictPose(const Frame& frame, bool imu_usable) const {
  if (!has_last_) return {};
  if (!imu_usable) {
    return {T_w_b_last_ * (has_motion_ ? motion_ : SE3d()), false, std::nullopt, std::nullopt};
  }
  if (std::optional<InertialPrediction> inertial = predictInertial(frame)) {
    const SE3d T_w_b = inertial->T_w_b;
    return {T_w_b, true, std::move(inertial), std::nullopt};
  }
  SE3d motion = has_motion_ ? motion_ : SE3d();
  const auto& samples = frame.imu;
  if (imu_ && samples.size() >= 2 && samples.front().t_ns <= t_last_ns_ &&
      samples.back().t_ns >= frame.t_ns && frame.t_ns > t_last_ns_) {
    imu::Preintegration preintegration(bias_, imu::ImuNoise::fromCalibration(*imu_));
    preintegration.integrateBetween(samples, t_last_ns_, frame.t_ns);
    if (options_.imu_translation_prediction && has_velocity_ && inertialReady()) {
      return {predictWithImu(preintegration), true, std::nullopt, std::nullopt};
    }
    const Eigen::Matrix3d R_b_i = imu_->T_b_i.rotation();
    const Eigen::Matrix3d dR = R_b_i * preintegration.deltaRotation() * R_b_i.transpose();
    motion = SE3d(Eigen::Quaterniond(dR).normalized(), motion.t);
    return {T_w_b_last_ * motion, true, std::nullopt, std::nullopt};
  }
  return {T_w_b_last_ * motion, false, std::nullopt, std::nullopt};
}

SE3d Tracker::predictWithImu(const imu::Preintegration& preintegration) const {
  const SE3d T_w_i = T_w_b_last_ * imu_->T_b_i;
  imu::NavState state;
  state.R_w_b = T_w_i.rotation();
  state.p_w = T_w_i.t;
  state.v_w = velocity_w_;
  const imu::NavState next = preintegration.predict(state, bias_);
  return SE3d(Eigen::Quaterniond(next.R_w_b).normalized(), next.p_w) * imu_->T_b_i.inverse();
}

std::optional<InertialPrediction> Tracker::predictInertial(const Frame& frame) const {
  // The tracker's own count, not the mapper's: the mapper's state belongs to the mapping thread.
  if (!imu_ || !has_map_ || !inertialInitialized() || localization_only_) return std::nullopt;
  return predictFromKeyFrame(referenceInertialState(), imu_since_keyframe_.samples(), frame.t_ns,
                             imu_->T_b_i, imu::ImuNoise::fromCalibration(*imu_),
                             options_.imu_prior);
}

map::KeyFrame Tracker::referenceInertialState() const {
  map::KeyFrame reference = inertialStateOf(*map_, reference_);
  const PredictionStart start = predictionStart();
  if (start.keyframe == reference_) return reference;
  const map::KeyFrame estimated = inertialStateOf(*map_, start.keyframe);
  const std::optional<InertialPrediction> carried =
      predictFromKeyFrame(estimated, start.samples, reference.t_ns, imu_->T_b_i,
                          imu::ImuNoise::fromCalibration(*imu_), options_.imu_prior);
  if (!carried) return reference;  // an IMU gap on the way: the reference's own state
  reference.v_w = carried->v_w;
  reference.bg = estimated.bg;
  reference.ba = estimated.ba;
  return reference;
}

Tracker::PredictionStart Tracker::predictionStart() const {
  // A keyframe's velocity and biases are the prediction it was inserted with until local inertial
  // BA estimates them. With a mapping thread that BA may wait behind others; taking them from such
  // a keyframe, whose velocity came from the same kind of prediction, chains IMU predictions with
  // no estimate ever correcting the velocity, and while the mapper is behind (keyframes every few
  // frames at car speed) the velocity drifts by metres per second until tracking fails. So they
  // come from the newest estimated keyframe, carried across the ones after it.
  constexpr int kMaxPredictionChain = 32;
  PredictionStart start{reference_, imu_since_keyframe_.samples()};
  for (int k = 0; k < kMaxPredictionChain; ++k) {
    bool estimated = true;
    map::KeyFrameId previous = map::kNoKeyFrame;
    std::vector<sensors::ImuSample> earlier;
    map_->readKeyFrame(start.keyframe, [&](const map::KeyFrame& kf) {
      estimated = kf.inertial_estimated;
      previous = kf.previous;
      if (!estimated) earlier = kf.imu_from_previous;
    });
    if (estimated) return start;
    if (previous == map::kNoKeyFrame) break;
    start = {previous, joinImuSamples(earlier, start.samples)};
  }
  return {reference_, imu_since_keyframe_.samples()};
}

std::optional<optim::PosePrior> Tracker::rotationPrior(const Prediction& prediction) const {
  if (prediction.inertial) return prediction.inertial->prior;
  if (!prediction.from_imu || !(options_.imu_rotation_prior_sigma_deg > 0.0)) return std::nullopt;
  const double sigma_rad = options_.imu_rotation_prior_sigma_deg * M_PI / 180.0;
  optim::PosePrior prior;
  prior.T_w_b = prediction.T_w_b;
  prior.information.setZero();
  prior.information.diagonal() << Eigen::Vector3d::Constant(1.0 / (sigma_rad * sigma_rad)),
      Eigen::Vector3d::Constant(1e-6);  // position: essentially free
  return prior;
}

SE3d Tracker::initialPose(const Frame& frame, const SE3d& predicted) const {
  if (has_last_) return predicted;  // a reset keeps the world frame of the lost map
  return gravityAlignedPose(frame);
}

SE3d Tracker::gravityAlignedPose(const Frame& frame) const {
  if (!imu_ || frame.imu.empty()) return SE3d();
  Eigen::Vector3d accel = Eigen::Vector3d::Zero();
  for (const sensors::ImuSample& s : frame.imu)
    accel += s.accel;
  const Eigen::Vector3d up_b = imu_->T_b_i.rotation() * accel;
  if (!(up_b.norm() > 1e-6)) return SE3d();
  return SE3d(Eigen::Quaterniond::FromTwoVectors(up_b, Eigen::Vector3d::UnitZ()),
              Eigen::Vector3d::Zero());
}

TrackingResult Tracker::track(const Frame& input) {
  TrackingResult result;
  result.t_ns = input.t_ns;
  result.times.extract_ms = input.extract_ms;
  result.times.stereo_ms = input.stereo_ms;
  const auto start = Clock::now();
  const bool imu_usable = collectImu(input, result);
  // The map-reading part of the frame holds the map's read lock (map.h): it sees each update of
  // the mapping thread entirely or not at all. Without a map it reads none, and starting a map
  // waits for the mapping thread, which must not find the lock held.
  map::Map::ReadLock reading;
  if (has_map_) {
    reading = map_->readLock();
    followMapCorrections();  // a loop closed since the last frame: its pose moves with the map
  }
  const Prediction prediction = predictPose(input, imu_usable);
  result.T_w_b = prediction.T_w_b;
  result.T_w_predicted = prediction.T_w_b;
  std::vector<int> kept;
  std::optional<Frame> without_moving;
  if (options_.dynamic.mode != dynamic::DynamicMode::kOff) {
    without_moving = removeMovingFeatures(input, prediction, result, kept);
  }
  const Frame& frame = without_moving ? *without_moving : input;
  if (localization_only_ && !located_) {
    const std::vector<map::MapPointId> tracked = locateInLoadedMap(frame, result);
    result.times.track_ms = millisecondsSince(start);
    rememberFrame(input, kept, tracked);
    if (located_) updateMotion(result.T_w_b, frame.t_ns);
    return result;
  }
  if (!has_map_ && isMonocular()) {
    initializeMono(frame, result);
    if (result.state == TrackingState::kInitialized) noteReference(result);
    result.times.track_ms = millisecondsSince(start);
    rememberFrame(input, kept, {});
    if (result.state == TrackingState::kInitialized) return result;  // motion set by the init
    updateMotion(result.T_w_b, frame.t_ns);
    return result;
  }
  if (!has_map_) {
    initializeAt(frame, initialPose(frame, prediction.T_w_b), result);
    // A frame that starts no map is a prediction in the left map: it is reported through that
    // map's reference keyframe, so that it follows the map if a merge brings it back.
    noteReference(result);
    result.times.track_ms = millisecondsSince(start);
    rememberFrame(input, kept, {});
    updateMotion(result.T_w_b, frame.t_ns);
    return result;
  }
  std::vector<map::MapPointId> tracked = trackFrame(frame, prediction, result);
  if (result.inliers < options_.min_inliers && !localization_only_) {
    if (!failing_) t_failed_ns_ = frame.t_ns;
    failing_ = true;
    if (withinRelocalizationWindow(frame)) {
      if (auto located = relocalize(frame, prediction, result)) tracked = std::move(*located);
    }
  }
  result.times.track_ms = millisecondsSince(start);
  bool wants_keyframe = false;
  bool reanchor = false;
  if (result.inliers < options_.min_inliers && canBridgeWithImu(frame, prediction)) {
    result.state = TrackingState::kRecentlyLost;  // result.T_w_b: the IMU prediction
  } else if (result.inliers < options_.min_inliers && localization_only_) {
    located_ = false;  // the next frames are located in the loaded map again
    result.state = TrackingState::kLost;
  } else if (result.inliers < options_.min_inliers && canReanchorWithImu(frame, prediction)) {
    result.state = TrackingState::kRecentlyLost;  // result.T_w_b: the IMU prediction
    reanchor = true;
  } else if (result.inliers < options_.min_inliers && withinRelocalizationWindow(frame)) {
    result.state = TrackingState::kLost;  // the map is kept: the next frames are relocalised
  } else if (result.inliers < options_.min_inliers) {
    has_map_ = false;  // lost: the next frame starts a new map at its predicted pose
    result.state = TrackingState::kLost;
    if (mono_initializer_) mono_initializer_->reset();
  } else {
    result.state = TrackingState::kTracking;
    t_tracked_ns_ = frame.t_ns;
    failing_ = false;
    wants_keyframe = !localization_only_ && needKeyFrame(frame, result.inliers);
    if (localization_only_) followTrackedKeyFrame(tracked);
  }
  noteReference(result);  // a frame lost for good too: the map it leaves may be merged back
  reading.unlock();       // a new keyframe is submitted to (and may wait for) the mapping thread
  if (reanchor) {
    // The IMU carries the map's frame over the failure: a keyframe at the predicted pose with new
    // stereo points, linked to the last one by the preintegration across the failure.
    addKeyFrameAndMap(frame, std::vector<map::MapPointId>(frame.size(), map::kNoMapPoint),
                      prediction, result);
    result.reanchored = true;
    t_tracked_ns_ = frame.t_ns;
    failing_ = false;
    ++reanchors_;
  } else if (wants_keyframe && mappingAcceptsKeyFrame(frame, result.inliers)) {
    addKeyFrameAndMap(frame, tracked, prediction, result);
  }
  if (result.keyframe) {
    result.reference = reference_;  // the frame itself: its pose is the keyframe's
    result.T_w_reference = result.T_w_b;
  }
  rememberFrame(input, kept, has_map_ ? tracked : std::vector<map::MapPointId>{});
  if (has_map_) {
    // A loop corrected since the frame was tracked moves the frame and its reference keyframe
    // alike: the pose relative to the keyframe stays what tracking measured.
    const map::KeyFrameCorrection correction = followMapCorrections(&result.T_w_b);
    result.T_w_reference = correction.apply(result.T_w_reference);
    result.T_w_predicted = correction.apply(result.T_w_predicted);
  }
  if (result.relocalized) {
    restartMotionAt(result.T_w_b, frame.t_ns, prediction);
  } else {
    updateMotion(result.T_w_b, frame.t_ns);
  }
  return result;
}

bool Tracker::collectImu(const Frame& frame, TrackingResult& result) {
  if (!imu_) return false;
  const std::optional<ImuGap> gap = findImuGap(frame.imu, secondsToNs(options_.imu_max_gap_s));
  if (!gap) {
    imu_since_keyframe_.append(frame.imu);
    return true;
  }
  imu_since_keyframe_.restartAt(frame.imu, gap->t1_ns);
  if (gap->t1_ns != last_imu_gap_end_ns_) result.imu_gap = gap;  // every frame in it meets it
  last_imu_gap_end_ns_ = gap->t1_ns;
  return false;
}

map::KeyFrameCorrection Tracker::followMapCorrections(SE3d* pose) {
  map::KeyFrameCorrection total;
  const std::vector<map::MapCorrection> corrections = map_->correctionsSince(corrections_followed_);
  for (const map::MapCorrection& correction : corrections) {
    const map::KeyFrameCorrection C = correction.correctionAt(t_last_ns_);
    T_w_b_last_ = C.apply(T_w_b_last_);
    velocity_w_ = C.scale * (C.C.rotation() * velocity_w_);
    motion_.t = C.scale * motion_.t;  // a monocular map's scale changed around the frame
    if (pose) *pose = C.apply(*pose);
    total = C.after(total);
  }
  corrections_followed_ += static_cast<int>(corrections.size());
  return total;
}

bool Tracker::mapSettled() const {
  if (!imu_ || !mapper_.options().inertial) return true;
  return inertial_inits_ > 0 &&
         !mapper_.inertialStageDue(inertial_inits_, std::numeric_limits<double>::infinity(),
                                   std::numeric_limits<int>::max());
}

void Tracker::initializeAt(const Frame& frame, const SE3d& T_w_b, TrackingResult& result) {
  result.T_w_b = T_w_b;
  if (frame.numStereo() < options_.min_inliers) return;  // stays lost: nothing to build a map on
  startMap(frame, T_w_b);
  result.state = TrackingState::kInitialized;
  result.keyframe = true;
}

std::vector<map::MapPointId> Tracker::trackFrame(const Frame& frame, const Prediction& prediction,
                                                 TrackingResult& result) {
  const bool motion_unknown = !prediction.inertial && !has_motion_;
  if (motion_unknown) {
    if (auto from_reference = trackFromReference(frame, result)) {
      return countObservations(std::move(*from_reference), true);
    }
  }
  LocalMapTrack track = trackLocalMap(frame, prediction, result);
  const bool tracked = result.inliers >= options_.min_inliers;
  // A weak search (fewer inliers than a reference pose needs) is often a wrong pose from a poor
  // prediction: the reference keyframe's pose replaces it when it reaches that bar.
  if (result.inliers < options_.reference_matching.min_inliers && !motion_unknown) {
    if (auto from_reference = trackFromReference(frame, result)) {
      return countObservations(std::move(*from_reference), true);
    }
  }
  return countObservations(std::move(track), tracked);
}

std::vector<map::MapPointId> Tracker::countObservations(LocalMapTrack track, bool found) {
  // The loaded map stays as it is; a frame that was not tracked (a blackout, a lost frame) says
  // nothing about whether the points it might have seen are there (ORB-SLAM counts only the
  // frames it tracks), so culling's found ratio counts neither.
  if (localization_only_ || !found) return std::move(track.tracked);
  for (const map::MapPointId id : track.visible)
    map_->increaseVisible(id);
  for (const map::MapPointId id : track.tracked)
    if (id != map::kNoMapPoint) map_->increaseFound(id);
  return std::move(track.tracked);
}

std::optional<Tracker::LocalMapTrack> Tracker::trackFromReference(const Frame& frame,
                                                                  TrackingResult& result) {
  if (!options_.reference_matching.enabled) return std::nullopt;
  const std::optional<ReferencePose> pose =
      poseFromReference(frame, referenceView(), T_b_c0_, 0.5 * (camera0_.fx() + camera0_.fy()),
                        options_.reference_matching);
  if (!pose) return std::nullopt;
  TrackingResult attempt = result;
  const Prediction from_reference{pose->T_w_b, false, std::nullopt,
                                  options_.reference_matching.search_radius_px};
  LocalMapTrack track = trackLocalMap(frame, from_reference, attempt);
  if (attempt.inliers < std::max(options_.min_inliers, options_.reference_matching.min_inliers)) {
    return std::nullopt;
  }
  attempt.from_reference = true;
  result = attempt;
  return track;
}

ReferenceView Tracker::referenceView(map::KeyFrameId id) const {
  // Copy the keyframe's observations first: map reads must not nest.
  std::vector<std::pair<map::MapPointId, features::Keypoint>> observed;
  std::vector<cv::Mat> rows;
  features::DescriptorType type = features::DescriptorType::kBinary;
  map_->readKeyFrame(id, [&](const map::KeyFrame& kf) {
    if (kf.descriptors.empty()) return;
    if (kf.descriptors.type() == CV_32FC1) type = features::DescriptorType::kFloat;
    for (std::size_t i = 0; i < kf.map_points.size(); ++i) {
      if (kf.map_points[i] == map::kNoMapPoint) continue;
      observed.emplace_back(kf.map_points[i], mapping::asFeatureKeypoint(kf.keypoints[i]));
      rows.push_back(kf.descriptors.row(static_cast<int>(i)).clone());
    }
  });
  ReferenceView view;
  view.features.descriptor_type = type;
  std::vector<cv::Mat> kept;
  for (std::size_t k = 0; k < observed.size(); ++k) {
    const std::optional<Eigen::Vector3d> p_w = map_->mapPointPosition(observed[k].first);
    if (!p_w) continue;
    view.features.keypoints.push_back(observed[k].second);
    kept.push_back(rows[k]);
    view.p_w.push_back(*p_w);
  }
  if (!kept.empty()) cv::vconcat(kept, view.features.descriptors);
  return view;
}

Tracker::LocalMapTrack Tracker::trackLocalMap(const Frame& frame, const Prediction& prediction,
                                              TrackingResult& result) {
  LocalMapTrack track;
  track.tracked.assign(frame.size(), map::kNoMapPoint);
  std::vector<map::MapPointId>& tracked = track.tracked;
  const std::vector<LocalPoint> points = localPoints();
  // A pose known to a few pixels is searched at its own radius, without the wide retry.
  const bool known_pose = prediction.search_radius_px.has_value();
  std::vector<features::Match> matches =
      matchLocalPoints(frame, points, prediction.T_w_b,
                       known_pose ? withRadius(options_.projection, *prediction.search_radius_px)
                                  : options_.projection,
                       !known_pose, &track.visible);
  result.matches = static_cast<int>(matches.size());
  for (const features::Match& m : matches) {
    int point_class = features::kClassBackground;
    map_->readMapPoint(points[static_cast<std::size_t>(m.query)].id,
                       [&](const map::MapPoint& p) { point_class = p.class_id; });
    if (point_class != frame.features.keypoints[static_cast<std::size_t>(m.train)].class_id) {
      ++result.cross_class_matches;
    }
  }
  if (result.matches < options_.min_inliers) return track;
  optim::PoseOptimizationResult pose =
      pose_optimizer_.optimize(prediction.T_w_b, cameras_, poseObservations(frame, points, matches),
                               rotationPrior(prediction));
  // The first matches.size() observations are the left ones; count and keep those.
  const auto leftInliers = [](const optim::PoseOptimizationResult& p, std::size_t left) {
    return static_cast<int>(
        std::count(p.inliers.begin(), p.inliers.begin() + static_cast<std::ptrdiff_t>(left), true));
  };
  result.inliers = leftInliers(pose, matches.size());
  if (options_.refine_radius_px > 0.0 && result.inliers >= options_.min_inliers) {
    if (auto refined = refineByReprojection(frame, points, prediction, pose, result.inliers)) {
      pose = std::move(refined->first);
      matches = std::move(refined->second);
      result.inliers = leftInliers(pose, matches.size());
    }
  }
  if (result.inliers < options_.min_inliers) return track;
  result.T_w_b = pose.T_w_b;
  for (std::size_t k = 0; k < matches.size(); ++k) {
    if (!pose.inliers[k]) continue;
    tracked[static_cast<std::size_t>(matches[k].train)] =
        points[static_cast<std::size_t>(matches[k].query)].id;
  }
  return track;
}

std::optional<std::pair<optim::PoseOptimizationResult, std::vector<features::Match>>>
Tracker::refineByReprojection(const Frame& frame, const std::vector<LocalPoint>& points,
                              const Prediction& prediction,
                              const optim::PoseOptimizationResult& pose, int inliers) {
  std::vector<features::Match> matches =
      matchLocalPoints(frame, points, pose.T_w_b,
                       withRadius(options_.projection, options_.refine_radius_px), false, nullptr);
  if (static_cast<int>(matches.size()) <= inliers) return std::nullopt;
  optim::PoseOptimizationResult refined = pose_optimizer_.optimize(
      pose.T_w_b, cameras_, poseObservations(frame, points, matches), rotationPrior(prediction));
  const int refined_inliers = static_cast<int>(
      std::count(refined.inliers.begin(),
                 refined.inliers.begin() + static_cast<std::ptrdiff_t>(matches.size()), true));
  if (refined_inliers <= inliers) return std::nullopt;
  return std::make_pair(std::move(refined), std::move(matches));
}

void Tracker::addKeyFrameAndMap(const Frame& frame, const std::vector<map::MapPointId>& tracked,
                                const Prediction& prediction, TrackingResult& result) {
  const auto start = Clock::now();
  std::optional<Eigen::Vector3d> v_w;
  if (prediction.inertial) v_w = prediction.inertial->v_w;
  const map::KeyFrameId id = insertKeyFrame(frame, result.T_w_b, tracked, v_w);
  result.keyframe = true;
  KeyFrameObserver* observer = mapSettled() ? observer_ : nullptr;
  const bool inertial = inertialInitialized();
  // With a mapping thread, the global BA after a loop is solved in a thread of its own and
  // applied by a later job; sequentially, at once (bit-identical runs).
  const bool threaded = mapping_sink_ != nullptr;
  const auto job = [this, map = map_.get(), id, observer, inertial, threaded] {
    if (threaded) mapper_.applyGlobalBundleAdjust(*map, false);
    mapper_.processKeyFrame(*map, id);
    if (!observer || !observer->keyFrameMapped(*map, id, inertial)) return;
    if (threaded) {
      mapper_.startGlobalBundleAdjust(*map);
    } else {
      mapper_.globalBundleAdjust(*map);
    }
  };
  if (mapping_sink_) {
    mapping_sink_->submit(job);
    if (options_.mono_inertial_wait_for_keyframe_ba && isMonocular() && imu_) {
      // The next predictions start from this keyframe's refined state and match its new points.
      mapping_sink_->waitIdle();
      followMapCorrections();  // the keyframe's pose below already has them
      result.T_w_b = map_->keyFramePose(id).value_or(result.T_w_b);
    }
  } else {
    job();
    followMapCorrections();  // the keyframe's pose below already has them
    result.T_w_b = map_->keyFramePose(id).value_or(result.T_w_b);
  }
  initializeInertialIfDue(result);
  updateBiasFromMap();
  result.times.local_ba_ms = millisecondsSince(start);
}

void Tracker::runMapping(std::function<void()> job) {
  if (mapping_sink_) {
    mapping_sink_->submit(std::move(job));
  } else {
    job();
  }
}

void Tracker::waitForMapping() {
  if (mapping_sink_) mapping_sink_->waitIdle();
}

void Tracker::initializeInertialIfDue(TrackingResult& result) {
  if (!imu_) return;
  const std::vector<map::KeyFrameId> ids = map_->keyFrameIds();
  TimeNs t_first = 0;
  map_->readKeyFrame(ids.front(), [&](const map::KeyFrame& kf) { t_first = kf.t_ns; });
  const double age_s = nsToSeconds(t_reference_ns_ - t_first);
  if (!mapper_.inertialStageDue(inertial_inits_, age_s, static_cast<int>(ids.size()))) return;
  waitForMapping();  // the estimation moves the whole map: no job may run meanwhile
  const mapping::LocalMappingResult mapping = mapper_.initializeInertialIfDue(*map_, reference_);
  if (!mapping.inertial_initialization) return;  // retried at the next keyframe
  ++inertial_inits_;
  if (mapping.world_change) {
    result.world_change = mapping.world_change;
    // The map moved into the gravity-aligned (monocular: also metric) frame: so does the state
    // kept here, camera-centred like the map (System re-expresses earlier poses the same way).
    const Sim3d& T = *mapping.world_change;
    T_w_b_last_ = mapping::transformBodyPose(T, T_w_b_last_, T_b_c0_);
    velocity_w_ = T.s * (T.R * velocity_w_);
    result.T_w_predicted = mapping::transformBodyPose(T, result.T_w_predicted, T_b_c0_);
  }
  result.T_w_b = map_->keyFramePose(reference_).value_or(result.T_w_b);
}

void Tracker::updateBiasFromMap() {
  if (inertial_inits_ == 0) return;
  const map::Map::ReadLock reading = map_->readLock();  // the chain and the biases of one state
  // Sequentially, local BA has just estimated the newest keyframe; with a mapping thread its BA
  // may still be queued (its biases are the ones this tracker gave it).
  map_->readKeyFrame(predictionStart().keyframe, [&](const map::KeyFrame& kf) {
    bias_ = {kf.bg, kf.ba};
  });
}

std::vector<optim::PoseObservation> Tracker::poseObservations(
    const Frame& frame, const std::vector<LocalPoint>& points,
    const std::vector<features::Match>& matches) const {
  std::vector<optim::PoseObservation> observations;
  const auto observe = [&](const features::Match& m, int camera, const Eigen::Vector2d& xy) {
    optim::PoseObservation o;
    o.p_w = points[static_cast<std::size_t>(m.query)].point.p_w;
    o.normalized = xy;
    o.octave = frame.features.keypoints[static_cast<std::size_t>(m.train)].octave;
    o.camera = camera;
    observations.push_back(o);
  };
  for (const features::Match& m : matches)
    observe(m, 0, frame.normalized[static_cast<std::size_t>(m.train)]);
  if (!options_.stereo_pose_observations) return observations;
  for (const features::Match& m : matches) {
    const auto& right = frame.right_normalized[static_cast<std::size_t>(m.train)];
    if (right) observe(m, 1, *right);
  }
  return observations;
}

void Tracker::updateMotion(const SE3d& T_w_b, TimeNs t_ns) {
  if (has_last_) {
    motion_ = T_w_b_last_.inverse() * T_w_b;
    has_motion_ = true;
  }
  if (has_last_ && imu_ && t_ns > t_last_ns_) {
    // Mean velocity of the IMU origin over the last step: the start state of the next prediction.
    const double dt_s = nsToSeconds(t_ns - t_last_ns_);
    velocity_w_ = ((T_w_b * imu_->T_b_i).t - (T_w_b_last_ * imu_->T_b_i).t) / dt_s;
    has_velocity_ = true;
  }
  T_w_b_last_ = T_w_b;
  t_last_ns_ = t_ns;
  has_last_ = true;
}

std::unique_ptr<map::Map> Tracker::newMap() const {
  map::MapOptions map_options;
  map_options.T_b_c = {T_b_c0_};
  map_options.scale_factor = pyramid_.scale_factor;
  map_options.num_levels = pyramid_.levels;
  if (!map_) return std::make_unique<map::Map>(map_options);
  return std::make_unique<map::Map>(map_options, map_->nextKeyFrameId(), map_->nextMapPointId());
}

void Tracker::replaceMap(std::unique_ptr<map::Map> next) {
  if (mapping_sink_) mapping_sink_->discardPending();  // no job may use the old map
  mapper_.abandonGlobalBundleAdjust();                 // nor the global BA's
  const bool keep = atlas_ && observer_ && mapSettled() && map_->numKeyFrames() >= 2;
  std::unique_ptr<map::Map> left = std::exchange(map_, std::move(next));
  if (keep) atlas_->add(std::shared_ptr<map::Map>(std::move(left)));
  if (observer_) observer_->mapReset();  // nor the observer's threads (the atlas's map: read only)
}

void Tracker::finishGlobalBundleAdjust() {
  if (has_map_) mapper_.applyGlobalBundleAdjust(*map_, true);
}

void Tracker::startMap(const Frame& frame, const SE3d& T_w_b) {
  if (map_->numKeyFrames() > 0) ++resets_;
  replaceMap(newMap());
  // Ids are unique over the run: the atlas maps' right-camera observations stay for their merge.
  runMapping([this, kept = atlas_ ? atlas_->keyFrameIds() : std::vector<map::KeyFrameId>{}] {
    mapper_.reset(kept);
  });
  corrections_followed_ = 0;
  inertial_inits_ = 0;
  failing_ = false;
  bias_ = {};
  SE3d pose = T_w_b;
  insertKeyFrame(frame, pose, std::vector<map::MapPointId>(frame.size(), map::kNoMapPoint));
  has_map_ = true;
}

void Tracker::noteReference(TrackingResult& result) const {
  if (const auto T_w_reference = map_->keyFramePose(reference_)) {
    result.reference = reference_;
    result.T_w_reference = *T_w_reference;
  }
}

std::set<map::MapPointId> Tracker::localPointIds() const {
  std::vector<map::KeyFrameId> keyframes =
      map_->bestCovisibleKeyFrames(reference_, options_.local_keyframes);
  keyframes.push_back(reference_);
  std::set<map::MapPointId> ids;
  for (const map::KeyFrameId id : keyframes) {
    map_->readKeyFrame(id, [&](const map::KeyFrame& kf) {
      for (const map::MapPointId p : kf.map_points)
        if (p != map::kNoMapPoint) ids.insert(p);
    });
  }
  return ids;
}

std::vector<Tracker::LocalPoint> Tracker::localPoints() const {
  const std::set<map::MapPointId> ids = localPointIds();
  std::vector<LocalPoint> points;
  points.reserve(ids.size());
  for (const map::MapPointId id : ids) {
    map_->readMapPoint(id, [&](const map::MapPoint& p) {
      if (p.bad) return;
      map::MapPoint geometry;
      geometry.p_w = p.p_w;
      geometry.normal_w = p.normal_w;
      geometry.min_distance_m = p.min_distance_m;
      geometry.max_distance_m = p.max_distance_m;
      points.push_back({id, std::move(geometry)});
    });
  }
  return points;
}

std::vector<features::Match> Tracker::matchLocalPoints(
    const Frame& frame, const std::vector<LocalPoint>& points, const SE3d& T_w_b,
    const features::ProjectionMatchOptions& options, bool allow_wide,
    std::vector<map::MapPointId>* visible_ids) {
  features::FeatureSet query;
  // Keep only the points that project into the image; remember their index in `points`.
  std::vector<int> visible;
  std::vector<Eigen::Vector2d> predicted;
  query.descriptor_type = frame.features.descriptor_type;  // map points keep the frames' type
  query.image_size = frame.features.image_size;
  std::vector<cv::Mat> rows;
  std::vector<bool> outside_limits;
  const Eigen::Vector3d centre_w = (T_w_b * T_b_c0_).t;
  for (std::size_t k = 0; k < points.size(); ++k) {
    const Eigen::Vector3d p_c = optim::worldToCamera(T_w_b, T_b_c0_, points[k].point.p_w);
    if (!(p_c.z() > 0.05)) continue;
    const auto pixel = camera0_.project(p_c);
    if (!pixel || !camera0_.isInImage(*pixel)) continue;
    cv::Mat descriptor;
    map_->readMapPoint(points[k].id, [&](const map::MapPoint& p) { descriptor = p.descriptor; });
    if (descriptor.empty()) continue;
    // Counted visible only from within its viewing limits (or when matched, below).
    const bool within =
        !options_.viewing_limits || map::withinViewingLimits(points[k].point, centre_w);
    if (visible_ids && within) visible_ids->push_back(points[k].id);
    outside_limits.push_back(!within);
    visible.push_back(static_cast<int>(k));
    predicted.push_back(*pixel);
    query.keypoints.push_back(queryKeypoint(points[k].id));
    if (options_.predict_octave && points[k].point.max_distance_m > 0.0) {
      query.keypoints.back().octave =
          map::predictedOctave(points[k].point, (points[k].point.p_w - centre_w).norm(),
                               pyramid_.scale_factor, pyramid_.levels);
    }
    rows.push_back(descriptor);
  }
  if (visible.empty()) return {};
  cv::vconcat(rows, query.descriptors);
  const features::KeypointGrid grid(frame.features.keypoints, frame.features.image_size);
  std::vector<features::Match> matches =
      features::matchByProjection(query, predicted, frame.features, grid, options);
  if (allow_wide && static_cast<int>(matches.size()) < options_.min_projection_matches) {
    features::ProjectionMatchOptions wide = options;
    wide.radius_px = options_.wide_radius_px;
    matches = features::matchByProjection(query, predicted, frame.features, grid, wide);
  }
  std::vector<features::Match> usable;  // undistortion may fail far out in the image
  for (features::Match m : matches) {
    if (!frame.normalized[static_cast<std::size_t>(m.train)].allFinite()) continue;
    const std::size_t k = static_cast<std::size_t>(m.query);
    if (visible_ids && outside_limits[k]) visible_ids->push_back(points[visible[k]].id);
    m.query = visible[k];
    usable.push_back(m);
  }
  return usable;
}

features::Keypoint Tracker::queryKeypoint(map::MapPointId id) const {
  // The keypoint of the point's oldest observation describes how its descriptor was seen (octave,
  // orientation) — for points of stereo keyframes and of the mapper's triangulation alike.
  std::optional<std::pair<map::KeyFrameId, int>> observation;
  map_->readMapPoint(id, [&](const map::MapPoint& p) {
    if (!p.observations.empty()) observation = *p.observations.begin();
  });
  features::Keypoint keypoint;
  if (!observation) return keypoint;
  map_->readKeyFrame(observation->first, [&](const map::KeyFrame& kf) {
    keypoint =
        mapping::asFeatureKeypoint(kf.keypoints[static_cast<std::size_t>(observation->second)]);
  });
  return keypoint;
}

bool Tracker::needKeyFrame(const Frame& frame, int inliers) const {
  if (!isMonocular() && frame.numStereo() < options_.keyframe_min_stereo) return false;
  const TimeNs since_keyframe = frame.t_ns - t_reference_ns_;
  const bool weak_inertial = options_.imu_weak_keyframes && isMonocular() &&
                             inertialInitialized() && weakTracking(inliers);
  if (imu_ && (isMonocular() || !inertialInitialized()) && !weak_inertial &&
      since_keyframe < secondsToNs(options_.imu_min_keyframe_interval_s)) {
    return false;
  }
  if (since_keyframe < secondsToNs(options_.keyframe_min_interval_s) && !weakTracking(inliers)) {
    return false;
  }
  if (since_keyframe >= secondsToNs(options_.keyframe_max_interval_s)) return true;
  if (inliers < options_.keyframe_min_tracked) return true;
  return inliers < options_.keyframe_tracked_ratio * referenceTrackedPoints();
}

bool Tracker::canBridgeWithImu(const Frame& frame, const Prediction& prediction) const {
  return prediction.inertial.has_value() &&
         frame.t_ns - t_tracked_ns_ <= secondsToNs(options_.imu_bridge_s);
}

bool Tracker::canReanchorWithImu(const Frame& frame, const Prediction& prediction) const {
  return options_.imu_reanchor && prediction.inertial.has_value() && !isMonocular() &&
         frame.t_ns - t_tracked_ns_ <= secondsToNs(options_.relocalization_s) &&
         frame.numStereo() >= std::max(options_.keyframe_min_stereo, options_.min_inliers);
}

bool Tracker::mappingAcceptsKeyFrame(const Frame& frame, int inliers) {
  if (!mapping_sink_ || !isMonocular() || !mapping_sink_->busy()) return true;
  // The mapper still works on the previous keyframe (its new points are not in the map yet).
  const bool overdue =
      frame.t_ns - t_reference_ns_ >= secondsToNs(options_.keyframe_max_interval_s);
  if (!options_.mono_wait_for_mapping && !weakTracking(inliers) && !overdue) {
    return false;  // asked again at the next frame
  }
  mapping_sink_->waitIdle();
  return true;
}

int Tracker::referenceTrackedPoints() const {
  std::vector<map::MapPointId> ids;
  map_->readKeyFrame(reference_, [&](const map::KeyFrame& kf) { ids = kf.map_points; });
  // As ORB-SLAM: points seen by three keyframes or more (two while the map has two keyframes).
  const int min_observations = map_->numKeyFrames() > 2 ? 3 : 2;
  int tracked = 0;
  for (const map::MapPointId id : ids) {
    if (id == map::kNoMapPoint) continue;
    map_->readMapPoint(id, [&](const map::MapPoint& p) {
      if (!p.bad && p.numObservations() >= min_observations) ++tracked;
    });
  }
  return tracked;
}

map::KeyFrameId Tracker::insertKeyFrame(const Frame& frame, SE3d& T_w_b,
                                        const std::vector<map::MapPointId>& tracked,
                                        const std::optional<Eigen::Vector3d>& v_w) {
  map::KeyFrame kf;
  kf.t_ns = frame.t_ns;
  kf.T_w_b = T_w_b;
  if (imu_) {
    // The IMU state starts from the prediction (or the mean velocity before the initialisation)
    // and the current bias; the samples since the previous keyframe define its preintegration.
    kf.v_w = v_w.value_or(velocity_w_);
    kf.bg = bias_.bg;
    kf.ba = bias_.ba;
    std::vector<sensors::ImuSample> samples = imu_since_keyframe_.startInterval(frame.t_ns);
    if (map_->numKeyFrames() > 0) kf.imu_from_previous = std::move(samples);
  }
  kf.descriptors = frame.features.descriptors.clone();
  kf.keypoints.resize(frame.size());
  for (std::size_t i = 0; i < frame.size(); ++i) {
    map::KeyFrameKeypoint& k = kf.keypoints[i];
    const features::Keypoint& source = frame.features.keypoints[i];
    k.pixel = source.pixel;
    k.normalized = frame.normalized[i];  // NaN (not valid()) when undistortion failed
    k.octave = source.octave;
    k.angle = source.angle;
    k.class_id = source.class_id;
    k.instance_id = source.instance_id;
    k.depth_m = frame.depth_m[i];
  }
  kf.map_points = tracked;
  map::KeyFrameId id = map::kNoKeyFrame;
  std::vector<map::MapPointId> created;
  {
    const map::Map::UpdateLock update = map_->updateLock();  // the keyframe with its new points
    // A loop corrected since the frame was tracked: the keyframe joins the corrected map.
    const map::KeyFrameCorrection correction = followMapCorrections(&T_w_b);
    kf.T_w_b = T_w_b;
    kf.v_w = correction.scale * (correction.C.rotation() * kf.v_w);
    id = map_->addKeyFrame(std::move(kf));
    created = createStereoPoints(frame, T_w_b, id, tracked);
  }
  runMapping([this, id, right = frame.right_normalized, created]() mutable {
    mapper_.addKeyFrame(id, std::move(right), created);
  });
  reference_ = id;
  t_reference_ns_ = frame.t_ns;
  return id;
}

std::vector<map::MapPointId> Tracker::createStereoPoints(
    const Frame& frame, const SE3d& T_w_b, map::KeyFrameId keyframe,
    const std::vector<map::MapPointId>& tracked) {
  std::vector<std::size_t> candidates;
  for (std::size_t i = 0; i < frame.size(); ++i) {
    if (frame.hasStereo(i) && tracked[i] == map::kNoMapPoint) candidates.push_back(i);
  }
  std::stable_sort(candidates.begin(), candidates.end(), [&](std::size_t a, std::size_t b) {
    return frame.depth_m[a] < frame.depth_m[b];
  });
  const double close_depth = options_.close_depth_baselines * baseline_m_;
  const SE3d T_w_c0 = T_w_b * T_b_c0_;
  std::vector<map::MapPointId> created;
  for (std::size_t k = 0; k < candidates.size(); ++k) {
    const std::size_t i = candidates[k];
    if (frame.depth_m[i] > close_depth && static_cast<int>(k) >= options_.min_new_points) break;
    map::MapPoint point;
    point.p_w = T_w_c0 * frame.p_c0[i];
    point.descriptor = frame.features.descriptors.row(static_cast<int>(i)).clone();
    point.class_id = frame.features.keypoints[i].class_id;
    point.instance_id = frame.features.keypoints[i].instance_id;
    const map::MapPointId id = map_->addMapPoint(std::move(point));
    map_->addObservation(id, keyframe, static_cast<int>(i));
    map_->updateNormalAndDistances(id);
    created.push_back(id);
  }
  return created;
}

}  // namespace superdyna::tracking
