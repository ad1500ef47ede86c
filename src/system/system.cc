#include "superdyna/system/system.h"

#include <algorithm>
#include <chrono>
#include <exception>
#include <stdexcept>
#include <thread>
#include <utility>

#include "superdyna/core/bounded_queue.h"
#include "superdyna/core/error.h"
#include "superdyna/features/extractor_factory.h"
#include "superdyna/mapping/map_inertial_alignment.h"

namespace superdyna::system {

SensorMode parseSensorMode(const std::string& name) {
  if (name == "stereo") return SensorMode::kStereo;
  if (name == "stereo-inertial") return SensorMode::kStereoInertial;
  if (name == "mono") return SensorMode::kMono;
  if (name == "mono-inertial") return SensorMode::kMonoInertial;
  throw OptionError("--mode", "unknown mode '" + name +
                                  "'; supported modes: stereo, stereo-inertial, mono, "
                                  "mono-inertial");
}

std::string toString(SensorMode mode) {
  switch (mode) {
    case SensorMode::kStereo:
      return "stereo";
    case SensorMode::kStereoInertial:
      return "stereo-inertial";
    case SensorMode::kMono:
      return "mono";
    case SensorMode::kMonoInertial:
      return "mono-inertial";
  }
  return "?";
}

bool usesImu(SensorMode mode) {
  return mode == SensorMode::kStereoInertial || mode == SensorMode::kMonoInertial;
}

bool isMonocular(SensorMode mode) {
  return mode == SensorMode::kMono || mode == SensorMode::kMonoInertial;
}

void SystemOptions::validate() const {
  front_end.validate();
  semantics.validate();
  tracker.validate();
  mapping.validate();
  loop.validate();
  if (frame_queue < 1) throw OptionError("frame_queue", "must be >= 1");
  if (mapping_queue < 1) throw OptionError("mapping_queue", "must be >= 1");
}

void applyClassWiseMatching(SystemOptions& options) {
  const bool class_wise = options.front_end.features.class_wise_matching;
  options.front_end.stereo.same_class_only = class_wise;
  options.tracker.projection.same_class_only = class_wise;
  options.tracker.reference_matching.matching.same_class_only = class_wise;
  options.tracker.mono_init.same_class_only = class_wise;
  options.mapping.triangulation.same_class_only = class_wise;
  options.mapping.fusion.same_class_only = class_wise;
}

namespace {

using Clock = std::chrono::steady_clock;

double secondsSince(Clock::time_point start) {
  return std::chrono::duration<double>(Clock::now() - start).count();
}

map::MapIdentity rigIdentity(const SystemOptions& options, const sensors::CameraCalibration& cam0,
                             const std::optional<sensors::CameraCalibration>& cam1,
                             const std::optional<sensors::ImuCalibration>& imu) {
  map::MapIdentity identity;
  identity.feature_type = features::toString(options.front_end.features.type);
  identity.sensor_mode = toString(options.mode);
  identity.cameras.push_back(cam0);
  if (cam1 && !isMonocular(options.mode)) identity.cameras.push_back(*cam1);
  if (imu && usesImu(options.mode)) identity.T_b_i = imu->T_b_i;
  return identity;
}

/// The type and width of the descriptors of the map's first keyframe that has some.
void setDescriptorIdentity(const map::MapContents& contents, map::MapIdentity& identity) {
  for (const map::KeyFrame& kf : contents.keyframes) {
    if (kf.descriptors.empty()) continue;
    identity.descriptor_type = kf.descriptors.type() == CV_32FC1 ? map::MapDescriptorType::kFloat
                                                                 : map::MapDescriptorType::kBinary;
    identity.descriptor_columns = kf.descriptors.cols;
    return;
  }
}

SystemOptions checkedOptions(SystemOptions options) {
  options.tracker.use_imu = usesImu(options.mode);
  // Triangulation between keyframes is the only source of new points of a monocular map.
  if (isMonocular(options.mode)) options.mapping.triangulate = true;
  // Stereo rigs triangulate between keyframes only what stereo cannot measure.
  options.mapping.triangulation.skip_stereo_keypoints = !isMonocular(options.mode);
  applyClassWiseMatching(options);
  options.validate();
  return options;
}

}  // namespace

System::System(const SystemOptions& options, const sensors::CameraCalibration& cam0,
               const std::optional<sensors::CameraCalibration>& cam1,
               const std::optional<sensors::ImuCalibration>& imu,
               std::unique_ptr<semantics::Segmenter> segmenter)
    : options_(checkedOptions(options)),
      front_end_(options_.front_end, cam0, isMonocular(options_.mode) ? std::nullopt : cam1),
      segmenter_(std::move(segmenter)),
      propagator_(options_.semantics.propagation),
      tracker_(
          options_.tracker,
          tracking::PyramidInfo{front_end_.pyramid().scale_factor, front_end_.pyramid().levels},
          options_.mapping, cam0, isMonocular(options_.mode) ? std::nullopt : cam1,
          usesImu(options_.mode) ? imu : std::nullopt) {
  identity_ = rigIdentity(options_, cam0, cam1, imu);
  if (usesImu(options_.mode) && !imu) {
    throw OptionError("--mode", toString(options_.mode) + " needs IMU calibration and samples");
  }
  if (!isMonocular(options_.mode) && !cam1) {
    throw OptionError("--mode", toString(options_.mode) + " needs a second camera");
  }
  if (options_.loop.enabled) {
    mapping::PointFusionOptions fusion = options_.mapping.fusion;
    fusion.sigma0_px = options_.mapping.sigma0_px;
    const CameraModel camera0 = cam0.cameraModel();
    loop_ = std::make_unique<LoopStage>(
        options_.loop, camera0, optim::ReprojectionCamera::from(camera0, cam0.T_b_c), fusion,
        options_.tracker.pose, !options_.deterministic, isMonocular(options_.mode));
    loop_->setAtlas(&atlas_);
    tracker_.setKeyFrameObserver(loop_.get());
    tracker_.setAtlas(&atlas_);
  }
  if (!options_.deterministic) {
    mapping_ = std::make_unique<MappingWorker>(static_cast<std::size_t>(options_.mapping_queue));
    tracker_.setMappingSink(mapping_.get());
  }
}

System::~System() {
  mapping_.reset();          // joins the mapping thread before the tracker its jobs use goes
  if (loop_) loop_->stop();  // ... and the loop thread before the tracker's map goes
}

void System::record(TimeNs t_ns, const tracking::TrackingResult& result) {
  if (result.world_change) {
    for (std::size_t i = map_start_; i < frames_.size(); ++i) {
      FrameRecord& frame = frames_[i];
      frame.online.T_w_x =
          mapping::transformBodyPose(*result.world_change, frame.online.T_w_x, tracker_.T_b_c0());
      frame.T_cr_c.t *= result.world_change->s;  // relative camera poses: the map's scale only
    }
  }
  if (result.state == tracking::TrackingState::kInitialized) map_start_ = frames_.size();
  if (result.state == tracking::TrackingState::kInitializing) {
    ++initializing_frames_;
    return;
  }
  if (result.state == tracking::TrackingState::kLocalizing) {
    ++localizing_frames_;
    return;
  }
  FrameRecord frame{{t_ns, result.T_w_b}, result.reference, {}};
  if (result.reference != map::kNoKeyFrame) {
    const SE3d& T_b_c = tracker_.T_b_c0();
    frame.T_cr_c = (result.T_w_reference * T_b_c).inverse() * (result.T_w_b * T_b_c);
  }
  frames_.push_back(frame);
}

Trajectory System::trajectory() const {
  Trajectory trajectory;
  trajectory.reserve(frames_.size());
  const SE3d& T_b_c = tracker_.T_b_c0();
  for (const FrameRecord& frame : frames_) {
    std::optional<SE3d> T_w_reference;
    if (frame.reference != map::kNoKeyFrame && tracker_.hasMap())
      T_w_reference = tracker_.map().resolvedKeyFramePose(frame.reference);
    if (!T_w_reference) {
      trajectory.push_back(frame.online);
      continue;
    }
    const SE3d T_w_c = (*T_w_reference * T_b_c) * frame.T_cr_c;
    trajectory.push_back({frame.online.t_ns, T_w_c * T_b_c.inverse()});
  }
  return trajectory;
}

Trajectory System::onlineTrajectory() const {
  Trajectory trajectory;
  trajectory.reserve(frames_.size());
  for (const FrameRecord& frame : frames_)
    trajectory.push_back(frame.online);
  return trajectory;
}

std::optional<map::MapFile> System::mapFile() const {
  if (!tracker_.hasMap() || tracker_.map().numKeyFrames() == 0) return std::nullopt;
  // Localization-only: the loaded map, unchanged, with its right-camera observations.
  std::map<map::KeyFrameId, map::RightKeypoints> right = loaded_right_;
  if (!tracker_.localizationOnly()) {
    for (const auto& [id, observations] : tracker_.mapper().rightObservations())
      right.emplace(id, observations);
  }
  map::MapFile file =
      map::makeMapFile(tracker_.map(), identity_, std::move(right), tracker_.inertialStages());
  setDescriptorIdentity(file.contents, file.identity);
  return file;
}

void System::localizeIn(const map::MapFile& file, const std::filesystem::path& name) {
  const std::string mismatch = map::identityMismatch(file.identity, identity_);
  if (!mismatch.empty()) throw InputError(InputLocation(name), "map file: " + mismatch);
  tracker_.localizeIn(map::buildMap(file), file.inertial_stages);
  loaded_right_ = file.right;
}

LoopSummary System::loopSummary() const {
  LoopSummary summary = loop_ ? loop_->summary() : LoopSummary{};
  summary.global_bas = tracker_.mapper().globalBaRuns();
  summary.global_ba_ms = tracker_.mapper().globalBaMilliseconds();
  summary.global_bas_dropped = tracker_.mapper().globalBasDropped();
  summary.atlas_maps = atlas_.numMaps();
  summary.atlas_keyframes = atlas_.numKeyFrames();
  return summary;
}

sensors::InstanceMasks System::segment(const sensors::FrameBundle& bundle) {
  const auto start = Clock::now();
  const semantics::Segmentation left = segmenter_->segment(bundle.image0, bundle.t_ns, 0);
  std::optional<semantics::Segmentation> right;
  if (!bundle.image1.empty() && front_end_.isStereo() &&
      options_.semantics.segmentsRightImage(*segmenter_)) {
    right = segmenter_->segment(bundle.image1, bundle.t_ns, 1);
  }
  segment_ms_ += 1e3 * secondsSince(start);
  return semantics::toInstanceMasks(left, right, segmenter_->idsNameObjects());
}

sensors::InstanceMasks System::propagate(const features::FeatureSet& left) {
  const auto start = Clock::now();
  sensors::InstanceMasks masks = propagator_.propagate(left);
  propagate_ms_ += 1e3 * secondsSince(start);
  ++propagated_frames_;
  return masks;
}

bool System::segmentsFrame(std::size_t built) const {
  const auto every = static_cast<std::size_t>(options_.semantics.every_n_frames);
  return built % every == 0 || !propagator_.hasReference();
}

void System::startSegmentation(const sensors::FrameBundle& bundle) {
  if (!segment_thread_) segment_thread_ = std::make_unique<TaskThread>();
  segmenting_bundle_ = bundle;
  segmented_masks_.reset();
  segment_thread_->run([this] { segmented_masks_ = segment(segmenting_bundle_); });
  segmenting_ = true;
}

sensors::InstanceMasks System::finishSegmentation() {
  segmenting_ = false;
  segment_thread_->wait();
  ++segmented_frames_;
  segmenting_bundle_ = {};
  return std::move(*segmented_masks_);
}

void System::discardSegmentation() {
  if (!segmenting_) return;
  segmenting_ = false;
  try {
    segment_thread_->wait();
  } catch (...) {  // the frame is not built: its segmentation's error does not matter
  }
  segmenting_bundle_ = {};
}

void System::segmentAhead(const sensors::FrameBundle& next) {
  if (!segmenter_ || next.masks || segmenting_) return;
  const std::size_t built = segmented_frames_ + propagated_frames_;  // the frame before `next`
  if (segmentsFrame(built) || !segmentsFrame(built + 1)) return;
  startSegmentation(next);
}

tracking::Frame System::buildSegmentedFrame(const sensors::FrameBundle& bundle,
                                            std::optional<sensors::InstanceMasks>& masks) {
  const bool fresh = segmentsFrame(segmented_frames_ + propagated_frames_);
  if (fresh && segmenting_ && segmenting_bundle_.t_ns != bundle.t_ns) {
    throw std::logic_error("System: a segmentation was started ahead for another frame");
  }
  if (fresh && !segmenting_) startSegmentation(bundle);
  tracking::Frame frame;
  try {
    frame = front_end_.build(bundle, [&](const features::FeatureSet& left) {
      masks = fresh ? finishSegmentation() : propagate(left);
      return masks;
    });
  } catch (...) {
    discardSegmentation();  // the job reads segmenting_bundle_: let it finish first
    throw;
  }
  if (masks) propagator_.setReference(*masks, frame.features);
  return frame;
}

tracking::Frame System::buildFrame(const sensors::FrameBundle& bundle) {
  if (!segmenter_ && !front_end_callback_) return front_end_.build(bundle);
  sensors::FrameBundle labelled = bundle;
  // Masks the reader gave (bundle.masks) take precedence over the segmenter.
  tracking::Frame frame = segmenter_ && !bundle.masks ? buildSegmentedFrame(bundle, labelled.masks)
                                                      : front_end_.build(bundle);
  if (front_end_callback_) front_end_callback_(labelled, frame);
  return frame;
}

void System::collectFrontEndTimes() {
  timings_.segment_ms = segment_ms_;
  timings_.segmented_frames = segmented_frames_;
  timings_.propagated_frames = propagated_frames_;
  timings_.propagate_ms = propagate_ms_;
  timings_.busy.extraction_helper_ms = front_end_.helperCpuMs();
  timings_.busy.segmentation_ms = segment_thread_ ? segment_thread_->cpuMs() : 0.0;
}

tracking::TrackingResult System::process(const sensors::FrameBundle& bundle) {
  const auto start = Clock::now();
  const double cpu_start = threadCpuMs();
  const tracking::Frame frame = buildFrame(bundle);
  timings_.busy.front_end_ms += threadCpuMs() - cpu_start;
  collectFrontEndTimes();
  const tracking::TrackingResult result = track(frame);
  timings_.wall_s += secondsSince(start);
  return result;
}

void System::countMovingObjects(const tracking::Frame& frame,
                                const dynamic::MovingObjectReport& report) {
  MovingObjectCounts& counts = timings_.moving_objects;
  counts.keypoints += static_cast<long>(frame.size());
  counts.dropped += report.dropped;
  counts.geometric_dropped += report.geometric_dropped;
  for (const dynamic::ObjectDecision& object : report.objects) {
    counts.moving += object.decision == dynamic::ObjectState::kMoving;
    counts.static_objects += object.decision == dynamic::ObjectState::kStatic;
    counts.unverified += object.decision == dynamic::ObjectState::kUnverified;
  }
}

tracking::TrackingResult System::track(const tracking::Frame& frame) {
  const double cpu_start = threadCpuMs();
  const tracking::TrackingResult result = tracker_.track(frame);
  timings_.busy.tracking_ms += threadCpuMs() - cpu_start;
  record(frame.t_ns, result);
  timings_.matches.stereo += frame.numStereo();
  timings_.matches.stereo_cross_class += frame.cross_class_stereo;
  timings_.matches.map += result.matches;
  timings_.matches.map_cross_class += result.cross_class_matches;
  countMovingObjects(frame, result.moving);
  ++timings_.frames;
  if (result.keyframe) {
    ++timings_.keyframes;
    keyframes_.push_back({{frame.t_ns, result.T_w_b}, result.reference});
  }
  timings_.total.extract_ms += result.times.extract_ms;
  timings_.total.stereo_ms += result.times.stereo_ms;
  timings_.total.track_ms += result.times.track_ms;
  timings_.total.local_ba_ms += result.times.local_ba_ms;
  timings_.total.moving_objects_ms += result.times.moving_objects_ms;
  if (result.state == tracking::TrackingState::kLost ||
      result.state == tracking::TrackingState::kRecentlyLost) {
    ++lost_frames_;  // bridged by the IMU or not, the frame was not tracked
  }
  if (result.from_reference) ++reference_frames_;
  return result;
}

void System::run(io::DatasetSource& source, const FrameCallback& on_frame) {
  // One record per frame, written as the run goes: no doubling and copying of the whole
  // trajectory's records on long runs (the untouched part of the block is not resident).
  frames_.reserve(frames_.size() + source.size());
  if (options_.deterministic) {
    runSequentially(source, on_frame);
  } else {
    runConcurrently(source, on_frame);
  }
  finish();
}

void System::runSequentially(io::DatasetSource& source, const FrameCallback& on_frame) {
  while (true) {
    const auto start = Clock::now();
    const double cpu_start = threadCpuMs();
    const std::optional<sensors::FrameBundle> bundle = source.next();
    timings_.busy.front_end_ms += threadCpuMs() - cpu_start;
    timings_.wall_s += secondsSince(start);
    if (!bundle) break;
    const tracking::TrackingResult result = process(*bundle);
    if (on_frame) on_frame(result);
  }
}

void System::runConcurrently(io::DatasetSource& source, const FrameCallback& on_frame) {
  const auto start = Clock::now();
  BoundedQueue<tracking::Frame> frames(static_cast<std::size_t>(options_.frame_queue));
  std::exception_ptr front_end_error;
  double front_end_ms = 0.0;
  std::thread front_end([&] {
    const double cpu_start = threadCpuMs();
    // Segmenting one frame in N, the front end reads a bundle ahead, so that the network starts
    // on a frame to be segmented while the frame before it is built (segmentAhead).
    const bool read_ahead = segmenter_ && options_.semantics.every_n_frames > 1;
    try {
      std::optional<sensors::FrameBundle> next = source.next();
      while (next) {
        const sensors::FrameBundle bundle = std::move(*next);
        next.reset();
        if (read_ahead) {
          next = source.next();
          if (next) segmentAhead(*next);
        }
        if (!frames.push(buildFrame(bundle))) break;  // tracking stopped early
        if (!read_ahead) next = source.next();
      }
    } catch (...) {
      front_end_error = std::current_exception();
    }
    discardSegmentation();
    front_end_ms = threadCpuMs() - cpu_start;
    frames.close();
  });
  // Whatever ends the tracking loop (the end of the frames or an error), stop the front end.
  const auto stop_front_end = [&] {
    frames.close();
    front_end.join();
    timings_.busy.front_end_ms += front_end_ms;
    collectFrontEndTimes();
    timings_.wall_s += secondsSince(start);
  };
  try {
    while (std::optional<tracking::Frame> frame = frames.pop()) {
      const tracking::TrackingResult result = track(*frame);
      if (on_frame) on_frame(result);
    }
  } catch (...) {
    stop_front_end();
    throw;
  }
  stop_front_end();
  if (front_end_error) std::rethrow_exception(front_end_error);
}

void System::finish() {
  if (!mapping_) return;
  const auto start = Clock::now();
  const auto account = [&] {
    timings_.wall_s += secondsSince(start);
    timings_.total.local_ba_ms += mapping_->busyMs() - mapping_wall_ms_;
    mapping_wall_ms_ = mapping_->busyMs();
    timings_.busy.mapping_ms = mapping_->cpuMs();
    if (loop_) timings_.busy.loop_ms = loop_->cpuMs();
  };
  try {
    mapping_->finish();
    if (loop_) loop_->finish();
    tracker_.finishGlobalBundleAdjust();
  } catch (...) {
    account();
    throw;
  }
  account();
}

Trajectory System::keyFrameTrajectory() const {
  Trajectory trajectory;
  for (const InsertedKeyFrame& k : keyframes_) {
    const bool in_map = tracker_.hasMap() && tracker_.map().resolvedKeyFramePose(k.id);
    if (!in_map) trajectory.push_back(k.pose);
  }
  if (tracker_.hasMap()) {
    const map::Map& map = tracker_.map();
    for (const map::KeyFrameId id : map.keyFrameIds()) {
      map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
        trajectory.push_back({kf.t_ns, kf.T_w_b});
      });
    }
  }
  std::stable_sort(trajectory.begin(), trajectory.end(),
                   [](const StampedPose& a, const StampedPose& b) { return a.t_ns < b.t_ns; });
  return trajectory;
}

std::size_t System::numKeyFrames() const {
  return tracker_.hasMap() ? tracker_.map().numKeyFrames() : 0;
}

std::size_t System::numMapPoints() const {
  return tracker_.hasMap() ? tracker_.map().numMapPoints() : 0;
}

std::size_t System::numCrossClassMapPoints() const {
  return tracker_.hasMap() ? tracker_.map().numCrossClassMapPoints() : 0;
}

std::vector<std::pair<Eigen::Vector3d, int>> System::mapPointPositions() const {
  std::vector<std::pair<Eigen::Vector3d, int>> points;
  if (!tracker_.hasMap()) return points;
  const map::Map& map = tracker_.map();
  for (const map::MapPointId id : map.mapPointIds()) {
    map.readMapPoint(id, [&](const map::MapPoint& point) {
      if (!point.bad) points.emplace_back(point.p_w, point.class_id);
    });
  }
  return points;
}

std::map<int, std::size_t> System::mapPointsPerInstance() const {
  std::map<int, std::size_t> counts;
  if (!tracker_.hasMap()) return counts;
  const map::Map& map = tracker_.map();
  for (const map::MapPointId id : map.mapPointIds()) {
    map.readMapPoint(id, [&](const map::MapPoint& point) {
      if (!point.bad) ++counts[point.instance_id];
    });
  }
  return counts;
}

}  // namespace superdyna::system
