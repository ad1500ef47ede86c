#include "superdyna/mapping/local_mapper.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <memory>
#include <set>
#include <utility>

#include "superdyna/core/error.h"
#include "superdyna/core/time.h"

namespace superdyna::mapping {

void LocalMapperOptions::validate() const {
  if (window_keyframes < 2) throw OptionError("mapping.window_keyframes", "must be >= 2");
  if (fixed_observer_keyframes < 0) {
    throw OptionError("mapping.fixed_observer_keyframes", "must be >= 0");
  }
  if (iterations < 1) throw OptionError("mapping.iterations", "must be >= 1");
  if (!(chi2_outlier > 0.0)) throw OptionError("mapping.chi2_outlier", "must be > 0");
  if (cull_after_keyframes < 1) throw OptionError("mapping.cull_after_keyframes", "must be >= 1");
  if (min_observations < 1) throw OptionError("mapping.min_observations", "must be >= 1");
  if (!(min_found_ratio >= 0.0 && min_found_ratio <= 1.0)) {
    throw OptionError("mapping.min_found_ratio", "must be in [0, 1]");
  }
  if (!(sigma0_px > 0.0)) throw OptionError("mapping.sigma0_px", "must be > 0");
  if (!(scale_factor > 1.0)) throw OptionError("mapping.scale_factor", "must be > 1");
  triangulation.validate();
  fusion.validate();
  keyframe_culling.validate();
  inertial_init.validate();
  if (!(refine_first_s >= 0.0)) throw OptionError("mapping.refine_first_s", "must be >= 0");
  if (!(refine_second_s >= 0.0)) throw OptionError("mapping.refine_second_s", "must be >= 0");
  if (full_ba_iterations < 1) throw OptionError("mapping.full_ba_iterations", "must be >= 1");
  if (inertial_window_keyframes < 2) {
    throw OptionError("mapping.inertial_window_keyframes", "must be >= 2");
  }
  if (!(inertial_free_anchor_velocity_below_s >= 0.0)) {
    throw OptionError("mapping.inertial_free_anchor_velocity_below_s", "must be >= 0");
  }
  if (inertial_fixed_covisible < 0) {
    throw OptionError("mapping.inertial_fixed_covisible", "must be >= 0");
  }
  if (inertial_iterations < 1) throw OptionError("mapping.inertial_iterations", "must be >= 1");
  if (global_ba_iterations < 0) throw OptionError("mapping.global_ba_iterations", "must be >= 0");
}

namespace {

PointFusionOptions fusionOptions(const LocalMapperOptions& options) {
  PointFusionOptions fusion = options.fusion;
  fusion.sigma0_px = options.sigma0_px;
  return fusion;
}

const optim::ReprojectionCamera& leftCamera(const std::vector<optim::ReprojectionCamera>& cameras) {
  if (cameras.empty()) throw OptionError("cameras", "the local mapper needs the left camera");
  return cameras.front();
}

}  // namespace

LocalMapper::LocalMapper(const LocalMapperOptions& options,
                         std::vector<optim::ReprojectionCamera> cameras,
                         const std::optional<sensors::ImuCalibration>& imu)
    : options_(options),
      cameras_(std::move(cameras)),
      imu_(imu),
      fuser_(fusionOptions(options), leftCamera(cameras_), optim::stereoBaseline(cameras_)) {
  options_.validate();
  if (options_.triangulate) {
    PointTriangulatorOptions triangulation = options_.triangulation;
    triangulation.sigma0_px = options_.sigma0_px;
    triangulation.scale_factor = options_.scale_factor;
    triangulator_.emplace(triangulation, cameras_.front());
  }
  if (imu_) preintegrations_.emplace(imu::ImuNoise::fromCalibration(*imu_));
}

void LocalMapper::addKeyFrame(map::KeyFrameId id, RightObservations right,
                              const std::vector<map::MapPointId>& new_points) {
  right_[id] = std::move(right);
  for (const map::MapPointId point : new_points)
    recent_points_.emplace_back(point, id);
}

LocalMapper::~LocalMapper() {
  abandonGlobalBundleAdjust();
}

void LocalMapper::reset(const std::vector<map::KeyFrameId>& kept) {
  abandonGlobalBundleAdjust();
  std::erase_if(right_, [&](const auto& entry) {
    return !std::binary_search(kept.begin(), kept.end(), entry.first);
  });
  recent_points_.clear();
  if (preintegrations_) preintegrations_->clear();
  initializations_ = 0;
}

LocalMappingResult LocalMapper::processKeyFrame(map::Map& map, map::KeyFrameId newest) {
  LocalMappingResult result;
  const bool inertial = imu_ && options_.inertial;
  if (triangulator_) {
    for (const map::MapPointId point : triangulator_->createPoints(map, newest))
      recent_points_.emplace_back(point, newest);
  }
  result.fusion = fuser_.fuse(map, newest);
  const BundleAdjustmentResult ba =
      inertialInitialized() ? inertialBundleAdjust(map, newest) : visualBundleAdjust(map, newest);
  result.observations += ba.observations;
  result.imu_edges += ba.imu_edges;
  cullRecentPoints(map, newest);
  CullingImu culling_imu;
  culling_imu.has_imu = inertial;
  culling_imu.inertial_window = inertialInitialized() ? options_.inertial_window_keyframes + 1 : 0;
  result.culled = cullRedundantKeyFrames(map, newest, options_.keyframe_culling, culling_imu);
  for (const map::KeyFrameId id : result.culled)
    right_.erase(id);
  if (preintegrations_ && !result.culled.empty()) preintegrations_->prune(map);
  return result;
}

std::vector<map::KeyFrameId> LocalMapper::localWindow(const map::Map& map,
                                                      map::KeyFrameId newest) const {
  std::vector<map::KeyFrameId> window =
      map.bestCovisibleKeyFrames(newest, options_.window_keyframes - 1);
  window.push_back(newest);
  std::sort(window.begin(), window.end());
  return window;
}

BundleAdjustmentSettings LocalMapper::settings(int iterations) const {
  BundleAdjustmentSettings settings;
  settings.iterations = iterations;
  settings.chi2_outlier = options_.chi2_outlier;
  settings.sigma0_px = options_.sigma0_px;
  settings.scale_factor = options_.scale_factor;
  return settings;
}

BundleAdjustmentResult LocalMapper::visualBundleAdjust(map::Map& map, map::KeyFrameId newest) {
  const std::vector<map::KeyFrameId> ids = localWindow(map, newest);
  if (ids.empty()) return {};
  BundleAdjustmentWindow window;
  // As ORB-SLAM's local BA: the keyframes outside the window that observe its points hold the
  // gauge with their observations (monocular maps: their scale too). A stereo window floats
  // between them (the map's first keyframe stays where it is; without observers the oldest
  // window keyframe is held). A monocular window also keeps its oldest keyframe held, as before:
  // observers seen with little parallax pin its scale only weakly (letting the window float lost
  // track on the 3 s street flight of tracker_test), and holding a second one froze every new
  // map's second keyframe at its two-view estimate.
  const bool monocular = cameras_.size() == 1;
  const map::KeyFrameId first = map.keyFrameIds().front();
  for (const map::KeyFrameId id : ids) {
    const bool held = id == first || (monocular && id == ids.front());
    (held ? window.fixed : window.optimised).push_back(id);
  }
  window.fixed_observers = options_.fixed_observer_keyframes;
  window.min_fixed = 1;
  return bundleAdjust(map, window, cameras_, right_, settings(options_.iterations));
}

namespace {

/// The newest `count` keyframes of the temporal chain ending at `newest`, newest first.
std::vector<map::KeyFrameId> temporalChain(const map::Map& map, map::KeyFrameId newest,
                                           std::size_t count) {
  std::vector<map::KeyFrameId> ids;
  map::KeyFrameId id = newest;
  while (id != map::kNoKeyFrame && ids.size() < count) {
    ids.push_back(id);
    map::KeyFrameId previous = map::kNoKeyFrame;
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) { previous = kf.previous; });
    id = previous;
  }
  return ids;
}

}  // namespace

BundleAdjustmentResult LocalMapper::inertialBundleAdjust(map::Map& map, map::KeyFrameId newest) {
  const std::vector<map::KeyFrameId> chain =
      temporalChain(map, newest, static_cast<std::size_t>(options_.inertial_window_keyframes) + 1);
  if (chain.size() < 2) return {};
  BundleAdjustmentWindow window;
  window.inertial = true;
  // The keyframe before the window is the fixed anchor (with its velocity and biases); when the
  // chain is shorter, its oldest keyframe (the first of the map) is.
  window.optimised.assign(chain.begin(), chain.end() - 1);
  window.fixed = {chain.back()};
  window.fixed_observers = options_.inertial_fixed_covisible;
  window.free_anchor_velocity_below_s = options_.inertial_free_anchor_velocity_below_s;
  return bundleAdjust(map, window, cameras_, right_, settings(options_.inertial_iterations),
                      BundleAdjustmentImu{imu_->T_b_i, &*preintegrations_});
}

BundleAdjustmentResult LocalMapper::fullInertialBundleAdjust(map::Map& map, double bias_sigma_gyro,
                                                             double bias_sigma_acc) {
  const std::vector<map::KeyFrameId> ids = map.keyFrameIds();
  if (ids.size() < 2) return {};
  const BundleAdjustmentWindow window = fullInertialWindow(ids, bias_sigma_gyro, bias_sigma_acc);
  return bundleAdjust(map, window, cameras_, right_, settings(options_.full_ba_iterations),
                      BundleAdjustmentImu{imu_->T_b_i, &*preintegrations_});
}

std::optional<BundleAdjustmentWindow> LocalMapper::globalWindow(const map::Map& map) const {
  if (options_.global_ba_iterations == 0) return std::nullopt;
  const std::vector<map::KeyFrameId> ids = map.keyFrameIds();
  if (ids.size() < 2) return std::nullopt;
  if (initializations_ > 0)
    return fullInertialWindow(ids, bias_prior_sigma_gyro_, bias_prior_sigma_acc_);
  BundleAdjustmentWindow window;
  window.fixed = {ids.front()};
  window.optimised.assign(ids.begin() + 1, ids.end());
  // A monocular map's scale gauge: the second keyframe is held too.
  if (cameras_.size() == 1) window.min_fixed = 2;
  return window;
}

std::optional<BundleAdjustmentImu> LocalMapper::globalImuContext() {
  if (initializations_ == 0) return std::nullopt;
  return BundleAdjustmentImu{imu_->T_b_i, &*preintegrations_};
}

BundleAdjustmentResult LocalMapper::globalBundleAdjust(map::Map& map) {
  const std::optional<BundleAdjustmentWindow> window = globalWindow(map);
  if (!window) return {};
  const auto start = std::chrono::steady_clock::now();
  const BundleAdjustmentResult result = bundleAdjust(
      map, *window, cameras_, right_, settings(options_.global_ba_iterations), globalImuContext());
  ++global_ba_runs_;
  global_ba_ms_ += millisecondsSince(start);
  return result;
}

void LocalMapper::startGlobalBundleAdjust(map::Map& map) {
  if (global_ba_thread_.outstanding()) {
    global_ba_requested_ = true;  // started once the running one has been taken
    return;
  }
  const std::optional<BundleAdjustmentWindow> window = globalWindow(map);
  if (!window) return;
  const auto start = std::chrono::steady_clock::now();
  global_ba_ = std::make_unique<DeferredBundleAdjustment>(
      map, *window, cameras_, right_, settings(options_.global_ba_iterations), globalImuContext());
  global_ba_ms_ += millisecondsSince(start);
  global_ba_thread_.run([ba = global_ba_.get(), &solve_ms = global_ba_solve_ms_] {
    const auto solve_start = std::chrono::steady_clock::now();
    ba->solve();
    solve_ms = millisecondsSince(solve_start);
  });
}

void LocalMapper::applyGlobalBundleAdjust(map::Map& map, bool wait) {
  while (global_ba_thread_.outstanding() && (wait || global_ba_thread_.finished())) {
    global_ba_thread_.wait();
    const std::unique_ptr<DeferredBundleAdjustment> ba = std::move(global_ba_);
    if (ba->generation() == map.correctionCount()) {
      const auto start = std::chrono::steady_clock::now();
      ba->apply();
      global_ba_ms_ += global_ba_solve_ms_ + millisecondsSince(start);
      ++global_ba_runs_;
    } else {
      ++global_bas_dropped_;  // a loop corrected the map meanwhile: the solution would undo it
    }
    if (std::exchange(global_ba_requested_, false)) startGlobalBundleAdjust(map);
  }
}

void LocalMapper::abandonGlobalBundleAdjust() {
  if (global_ba_) global_ba_->abort();
  global_ba_thread_.wait();
  global_ba_.reset();
  global_ba_requested_ = false;
}

double LocalMapper::mapAgeSeconds(const map::Map& map, map::KeyFrameId newest) const {
  const std::vector<map::KeyFrameId> ids = map.keyFrameIds();
  TimeNs t_first = 0;
  TimeNs t_newest = 0;
  if (ids.empty()) return 0.0;
  map.readKeyFrame(ids.front(), [&](const map::KeyFrame& kf) { t_first = kf.t_ns; });
  map.readKeyFrame(newest, [&](const map::KeyFrame& kf) { t_newest = kf.t_ns; });
  return nsToSeconds(t_newest - t_first);
}

bool LocalMapper::inertialStageDue(int stage, double map_age_s, int keyframes) const {
  if (!imu_ || !options_.inertial) return false;
  switch (stage) {
    case 0:
      return keyframes >= options_.inertial_init.min_keyframes &&
             map_age_s >= options_.inertial_init.min_duration_s;
    case 1:
      return options_.refine_first_s > 0.0 && map_age_s >= options_.refine_first_s;
    case 2:
      return options_.refine_second_s > 0.0 && map_age_s >= options_.refine_second_s;
    default:
      return false;
  }
}

LocalMappingResult LocalMapper::initializeInertialIfDue(map::Map& map, map::KeyFrameId newest) {
  LocalMappingResult result;
  if (!imu_ || !options_.inertial) return result;
  if (!inertialStageDue(initializations_, mapAgeSeconds(map, newest),
                        static_cast<int>(map.numKeyFrames()))) {
    return result;
  }
  InertialMapInitOptions init = options_.inertial_init;
  init.estimate_scale = cameras_.size() == 1;  // a monocular map has no metric scale yet
  if (initializations_ >= 1) {
    // ORB-SLAM3's refinements: biases mostly free (gyroscope), the accelerometer's prior relaxed
    // at the first refinement and free at the second.
    init.gyro_bias_prior_sigma = 1.0;
    init.accel_bias_prior_sigma = initializations_ == 1 ? 0.1 : 1.0;
  }
  const InertialMapInitResult applied =
      initializeInertialMap(map, imu_->T_b_i, preintegrations_->noise(), init);
  if (!applied.applied) return result;
  preintegrations_->clear();  // the biases changed everywhere
  ++initializations_;
  result.inertial_initialization = true;
  result.world_change = applied.T_new_old;
  bias_prior_sigma_gyro_ = init.gyro_bias_prior_sigma;
  bias_prior_sigma_acc_ = applied.accel_bias_prior_sigma;
  const BundleAdjustmentResult ba =
      fullInertialBundleAdjust(map, bias_prior_sigma_gyro_, bias_prior_sigma_acc_);
  result.observations += ba.observations;
  result.imu_edges += ba.imu_edges;
  return result;
}

void LocalMapper::cullRecentPoints(map::Map& map, map::KeyFrameId newest) {
  const map::Map::UpdateLock update = map.updateLock();  // one map update
  std::vector<std::pair<map::MapPointId, map::KeyFrameId>> keep;
  for (const auto& [point, created] : recent_points_) {
    if (!map.hasMapPoint(point)) continue;
    if (newest - created < options_.cull_after_keyframes) {
      keep.emplace_back(point, created);
      continue;
    }
    const auto mp = map.mapPoint(point);
    if (mp->numObservations() < options_.min_observations ||
        mp->foundRatio() < options_.min_found_ratio) {
      map.eraseMapPoint(point);
    }
  }
  recent_points_ = std::move(keep);
}

}  // namespace superdyna::mapping
