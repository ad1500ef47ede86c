#include "superdyna/mapping/bundle_adjustment.h"

#include <ceres/ceres.h>
#include <spdlog/spdlog.h>

#include <algorithm>
#include <atomic>
#include <memory>
#include <set>
#include <stdexcept>

#include "superdyna/optim/imu_factors.h"
#include "superdyna/optim/se3_manifold.h"
#include "superdyna/optim/solver_options.h"

namespace superdyna::mapping {

namespace {

/// One reprojection residual, kept to classify it after solving.
struct BaObservation {
  map::MapPointId point = map::kNoMapPoint;
  map::KeyFrameId keyframe = map::kNoKeyFrame;
  std::shared_ptr<optim::ReprojectionFactor> factor;
  bool left = true;  ///< Right-camera residuals are not removed individually.
};

/// A reprojection residual before it joins the problem.
struct BaCandidate {
  BaObservation observation;
  bool valid = false;  ///< Evaluable (point in front of the camera) at the initial state.
};

/// Non-owning wrapper so the BaObservation list can evaluate the factors after solving.
class BorrowedFactor final : public ceres::SizedCostFunction<2, 7, 3> {
 public:
  explicit BorrowedFactor(const optim::ReprojectionFactor* factor) : factor_(factor) {}
  bool Evaluate(double const* const* parameters, double* residuals,
                double** jacobians) const override {
    return factor_->Evaluate(parameters, residuals, jacobians);
  }

 private:
  const optim::ReprojectionFactor* factor_;
};

/// Stops a solve between iterations once `abort` is set (an abandoned global BA).
class AbortCallback final : public ceres::IterationCallback {
 public:
  explicit AbortCallback(const std::atomic<bool>* abort) : abort_(abort) {}
  ceres::CallbackReturnType operator()(const ceres::IterationSummary&) override {
    return abort_->load() ? ceres::SOLVER_ABORT : ceres::SOLVER_CONTINUE;
  }

 private:
  const std::atomic<bool>* abort_;
};

/// The state blocks of one keyframe. The pose block holds T_w_b (visual) or T_w_i (inertial).
struct KeyFrameBlocks {
  optim::ImuStateParameters state;
  bool fixed = false;
  map::KeyFrameId previous = map::kNoKeyFrame;
  TimeNs t_ns = 0;
};

}  // namespace

namespace detail {

/// The problem of one BA in three steps: prepare() reads the map and builds the problem, solve()
/// touches no map, write() writes the result (at once, or into a map that has moved on).
class Problem {
 public:
  Problem(map::Map& map, const BundleAdjustmentWindow& window,
          const std::vector<optim::ReprojectionCamera>& cameras,
          const BundleAdjustmentSettings& settings, const std::optional<BundleAdjustmentImu>& imu)
      : map_(map), window_(window), settings_(settings), imu_(imu) {
    if (window.inertial && (!imu || imu->preintegrations == nullptr)) {
      throw std::invalid_argument("bundleAdjust: an inertial window needs the IMU context");
    }
    // Inertial: poses are IMU poses, so the cameras are expressed in the IMU frame.
    const SE3d T_i_b = window.inertial ? imu->T_b_i.inverse() : SE3d();
    for (optim::ReprojectionCamera camera : cameras) {
      camera.T_b_c = T_i_b * camera.T_b_c;
      cameras_.push_back(camera);
    }
    problem_options_.cost_function_ownership = ceres::TAKE_OWNERSHIP;
    problem_options_.manifold_ownership = ceres::TAKE_OWNERSHIP;
    problem_ = std::make_unique<ceres::Problem>(problem_options_);
  }

  /// Loads the state and builds the problem. `right` is read only here.
  void prepare(const std::map<map::KeyFrameId, RightObservations>& right) {
    right_ = &right;
    stage_ = prepareStage();
    right_ = nullptr;
    result_.observations = static_cast<int>(observations_.size());
  }

  /// Solves a prepared problem; touches no map (the global BA runs it in a thread of its own).
  /// `abort`: polled between iterations, true stops the solve (its solution is then not used).
  void solve(const std::atomic<bool>* abort = nullptr) {
    if (stage_ == Stage::kSolve && !solveProblem(abort)) stage_ = Stage::kRemoveInvalid;
  }

  /// Writes the solution as one map update: readers under the map's read lock see the whole
  /// result or none of it. `moved_on`: the map has changed since prepare() (the global BA in its
  /// own thread): the solved keyframes and points take the solution; the other keyframes (added
  /// meanwhile) move with the correction of their temporal predecessor (its solution relative to
  /// its pose now), the other points with that of their oldest observer; outliers still observed
  /// are removed; every keyframe's correction is recorded (Map::recordCorrection), so poses held
  /// outside the map follow. Keyframes and points removed meanwhile are skipped.
  BundleAdjustmentResult write(bool moved_on) {
    if (stage_ == Stage::kNothing) return result_;
    const map::Map::UpdateLock update = map_.updateLock();
    if (stage_ != Stage::kSolve) {
      result_.outliers = removeInvalidAtStart();  // no solution: the state stays as it was
      return result_;
    }
    std::map<map::KeyFrameId, map::KeyFrameCorrection> corrections;
    if (moved_on) {
      corrections = moveKeyFrames();
      movePoints(corrections);
    } else {
      writeBack();
    }
    result_.outliers = removeInvalidAtStart() + removeOutliers();
    if (moved_on) recordCorrections(corrections);
    return result_;
  }

 private:
  /// What a prepared problem leaves to do.
  enum class Stage {
    kNothing,        ///< No keyframe or no pair to optimise: the map stays as it is.
    kRemoveInvalid,  ///< No solution: only the observations behind a camera at the start go.
    kSolve,          ///< Solve, then write the solution.
  };

  Stage prepareStage() {
    loadKeyFrames();
    if (optimisedCount() == 0) return Stage::kNothing;
    const std::set<map::MapPointId> local = optimisedPoints();
    loadFixedObservers(local);
    holdOldestForGauge();
    if (blocks_.size() < 2 || optimisedCount() == 0) return Stage::kNothing;
    loadPoints(local);
    addReprojections(collectReprojections());
    if (observations_.empty()) return Stage::kRemoveInvalid;
    setPoseManifolds();
    if (window_.inertial) result_.imu_edges = addInertialFactors();
    return Stage::kSolve;
  }

  int optimisedCount() const {
    return static_cast<int>(std::count_if(blocks_.begin(), blocks_.end(),
                                          [](const auto& b) { return !b.second.fixed; }));
  }

  void setPoseManifolds() {
    for (auto& [id, blocks] : blocks_) {
      double* pose = blocks.state.pose.data();
      if (!problem_->HasParameterBlock(pose)) continue;
      const bool gauge = id == window_.gauge && !blocks.fixed;
      if (gauge && window_.inertial) {
        problem_->SetManifold(pose, new optim::RollPitchPoseManifold());
        continue;
      }
      problem_->SetManifold(pose, new optim::SE3Manifold());
      if (blocks.fixed || gauge) problem_->SetParameterBlockConstant(pose);
    }
  }

  void loadKeyFrame(map::KeyFrameId id, bool fixed) {
    if (blocks_.contains(id)) return;
    map_.readKeyFrame(id, [&](const map::KeyFrame& kf) {
      keyframes_.emplace(id, kf);
      KeyFrameBlocks blocks;
      const SE3d pose = window_.inertial ? kf.T_w_b * imu_->T_b_i : kf.T_w_b;
      blocks.state.pose = optim::toPoseBlock(pose);
      std::copy(kf.v_w.data(), kf.v_w.data() + 3, blocks.state.velocity.begin());
      std::copy(kf.bg.data(), kf.bg.data() + 3, blocks.state.bias_gyro.begin());
      std::copy(kf.ba.data(), kf.ba.data() + 3, blocks.state.bias_acc.begin());
      blocks.fixed = fixed;
      blocks.previous = kf.previous;
      blocks.t_ns = kf.t_ns;
      blocks_.emplace(id, blocks);
    });
  }

  void loadKeyFrames() {
    for (const map::KeyFrameId id : window_.optimised)
      loadKeyFrame(id, false);
    for (const map::KeyFrameId id : window_.fixed)
      loadKeyFrame(id, true);
  }

  /// The map points observed by the optimised keyframes.
  std::set<map::MapPointId> optimisedPoints() const {
    std::set<map::MapPointId> points;
    for (const auto& [id, kf] : keyframes_) {
      if (blocks_.at(id).fixed) continue;
      for (const map::MapPointId p : kf.map_points)
        if (p != map::kNoMapPoint) points.insert(p);
    }
    return points;
  }

  /// Keyframes outside the problem observing its points join it as fixed keyframes, those sharing
  /// most points first, up to window.fixed_observers.
  void loadFixedObservers(const std::set<map::MapPointId>& local) {
    if (window_.fixed_observers <= 0) return;
    std::map<map::KeyFrameId, int> shared;
    for (const map::MapPointId p : local) {
      map_.readMapPoint(p, [&](const map::MapPoint& point) {
        for (const auto& [observer, index] : point.observations)
          if (!blocks_.contains(observer)) ++shared[observer];
      });
    }
    std::vector<std::pair<int, map::KeyFrameId>> ranked;
    for (const auto& [id, count] : shared)
      ranked.emplace_back(-count, id);
    std::sort(ranked.begin(), ranked.end());
    const std::size_t n =
        std::min(ranked.size(), static_cast<std::size_t>(window_.fixed_observers));
    for (std::size_t k = 0; k < n; ++k)
      loadKeyFrame(ranked[k].second, true);
  }

  /// Holds the oldest optimised keyframes until window.min_fixed keyframes are fixed.
  void holdOldestForGauge() {
    int fixed = static_cast<int>(blocks_.size()) - optimisedCount();
    for (auto& [id, blocks] : blocks_) {
      if (fixed >= window_.min_fixed) return;
      if (blocks.fixed) continue;
      blocks.fixed = true;
      ++fixed;
    }
  }

  const RightObservations* rightOf(map::KeyFrameId id) const {
    const auto it = right_->find(id);
    return it == right_->end() ? nullptr : &it->second;
  }

  static bool hasRight(const RightObservations* right, std::size_t i) {
    return right != nullptr && i < right->size() && (*right)[i].has_value();
  }

  /// The local points (those of the optimised keyframes) with two or more residuals.
  void loadPoints(const std::set<map::MapPointId>& local) {
    std::map<map::MapPointId, int> counts;  // residuals per point
    for (const auto& [id, kf] : keyframes_) {
      const RightObservations* right = rightOf(id);
      for (std::size_t i = 0; i < kf.map_points.size(); ++i) {
        if (kf.map_points[i] == map::kNoMapPoint || !local.contains(kf.map_points[i])) continue;
        counts[kf.map_points[i]] += hasRight(right, i) ? 2 : 1;
      }
    }
    for (const auto& [id, count] : counts) {
      if (count < 2) continue;
      if (const auto p = map_.mapPointPosition(id)) points_.emplace(id, *p);
    }
  }

  BaCandidate newCandidate(map::KeyFrameId kf_id, map::MapPointId point_id, int camera,
                           const Eigen::Vector2d& normalized, int octave) const {
    const double sigma = optim::octaveSigmaPx(octave, settings_.sigma0_px, settings_.scale_factor);
    auto factor = std::make_shared<optim::ReprojectionFactor>(
        normalized, cameras_[static_cast<std::size_t>(camera)], sigma);
    const auto r = factor->residual(optim::fromPoseBlock(blocks_.at(kf_id).state.pose.data()),
                                    points_.at(point_id));
    return {{point_id, kf_id, factor, camera == 0}, r.has_value() && r->allFinite()};
  }

  /// Every reprojection of the loaded points, evaluated at the initial state.
  std::vector<BaCandidate> collectReprojections() const {
    std::vector<BaCandidate> candidates;
    for (const auto& [id, kf] : keyframes_) {
      const RightObservations* right = rightOf(id);
      for (std::size_t i = 0; i < kf.map_points.size(); ++i) {
        const map::MapPointId point_id = kf.map_points[i];
        if (point_id == map::kNoMapPoint || !points_.contains(point_id)) continue;
        if (!kf.keypoints[i].valid()) continue;  // undistortion failed: no observation
        candidates.push_back(
            newCandidate(id, point_id, 0, kf.keypoints[i].normalized, kf.keypoints[i].octave));
        if (cameras_.size() > 1 && hasRight(right, i)) {
          candidates.push_back(newCandidate(id, point_id, 1, *(*right)[i], kf.keypoints[i].octave));
        }
      }
    }
    return candidates;
  }

  /// Ceres abandons the whole solve when a residual cannot be evaluated at the initial state (a
  /// point behind a camera), so such reprojections stay out of the problem; their left
  /// observations are removed afterwards like any outlier. Points left with fewer than 2 residuals
  /// are not optimised (as in loadPoints).
  void addReprojections(const std::vector<BaCandidate>& candidates) {
    std::map<map::MapPointId, int> valid_counts;
    for (const BaCandidate& c : candidates) {
      if (c.valid) ++valid_counts[c.observation.point];
    }
    for (const auto& [id, count] : valid_counts) {
      if (count < 2) points_.erase(id);
    }
    for (const BaCandidate& c : candidates) {
      const BaObservation& o = c.observation;
      if (!c.valid) {
        invalid_at_start_.push_back(o);
        continue;
      }
      if (!points_.contains(o.point)) continue;
      problem_->AddResidualBlock(
          new BorrowedFactor(o.factor.get()), optim::newHuberLoss(settings_.chi2_outlier),
          blocks_.at(o.keyframe).state.pose.data(), points_.at(o.point).data());
      observations_.push_back(o);
    }
    for (const BaObservation& o : invalid_at_start_) {
      if (!valid_counts.contains(o.point)) points_.erase(o.point);  // no valid residual at all
    }
  }

  /// Preintegration and bias random walk from each optimised keyframe's predecessor (when in the
  /// problem); the inertial blocks of fixed keyframes are held constant.
  int addInertialFactors() {
    int edges = 0;
    for (auto& [id, blocks] : blocks_) {
      if (blocks.fixed) continue;
      const auto previous = blocks_.find(blocks.previous);
      if (previous == blocks_.end()) continue;
      const imu::Preintegration* pre = imu_->preintegrations->fromPrevious(map_, id);
      if (pre == nullptr) continue;
      const optim::ImuStateBlocks state_i = previous->second.state.blocks();
      const optim::ImuStateBlocks state_j = blocks.state.blocks();
      optim::addImuEdge(*problem_, *pre, state_i, state_j);
      if (previous->second.fixed) {
        holdInertialState(state_i, pre->deltaTime() < window_.free_anchor_velocity_below_s);
      }
      ++edges;
    }
    addBiasPrior();
    return edges;
  }

  void holdInertialState(const optim::ImuStateBlocks& state, bool free_velocity) {
    problem_->SetParameterBlockConstant(state.pose);
    if (!free_velocity) problem_->SetParameterBlockConstant(state.velocity);
    problem_->SetParameterBlockConstant(state.bias_gyro);
    problem_->SetParameterBlockConstant(state.bias_acc);
  }

  void addBiasPrior() {
    if (!(window_.bias_prior_sigma_gyro > 0.0 && window_.bias_prior_sigma_acc > 0.0)) return;
    for (auto& [id, blocks] : blocks_) {
      if (blocks.fixed) continue;
      const optim::ImuStateBlocks state = blocks.state.blocks();
      if (!problem_->HasParameterBlock(state.bias_gyro)) continue;
      optim::addBiasPrior(*problem_, state, imu::Bias{}, window_.bias_prior_sigma_gyro,
                          window_.bias_prior_sigma_acc);
      return;  // the oldest optimised keyframe only
    }
  }

  /// False (with a warning) when Ceres gives no usable solution; the state is then not written.
  /// Also false, quietly, when `abort` stopped it.
  bool solveProblem(const std::atomic<bool>* abort) {
    ceres::Solver::Options solver =
        optim::quietSolverOptions(ceres::DENSE_SCHUR, settings_.iterations);
    AbortCallback stop(abort);
    if (abort != nullptr) solver.callbacks.push_back(&stop);
    ceres::Solver::Summary summary;
    ceres::Solve(solver, problem_.get(), &summary);
    if (summary.termination_type == ceres::USER_FAILURE) return false;
    if (summary.IsSolutionUsable()) return true;
    spdlog::warn("{} bundle adjustment of {} keyframes failed, map left unchanged: {}",
                 window_.inertial ? "inertial" : "visual", optimisedCount(), summary.message);
    return false;
  }

  SE3d bodyPose(const KeyFrameBlocks& blocks) const {
    const SE3d pose = optim::fromPoseBlock(blocks.state.pose.data());
    return window_.inertial ? pose * imu_->T_b_i.inverse() : pose;
  }

  void writeKeyFrame(map::KeyFrameId id, const KeyFrameBlocks& blocks) {
    map_.setKeyFramePose(id, bodyPose(blocks));
    if (!window_.inertial) return;
    const imu::Bias bias = blocks.state.bias();
    const Eigen::Vector3d v_w(blocks.state.velocity[0], blocks.state.velocity[1],
                              blocks.state.velocity[2]);
    map_.setKeyFrameInertialState(id, v_w, bias.bg, bias.ba);
  }

  void writeBack() {
    for (const auto& [id, blocks] : blocks_)
      if (!blocks.fixed) writeKeyFrame(id, blocks);
    for (const auto& [id, p_w] : points_)
      map_.setMapPointPosition(id, p_w);
  }

  /// Solved keyframes take the solution, the others (not in the problem, added since prepare())
  /// their predecessor's correction, by increasing id (time); fixed ones stay. Returns every
  /// keyframe's correction.
  std::map<map::KeyFrameId, map::KeyFrameCorrection> moveKeyFrames() {
    std::map<map::KeyFrameId, map::KeyFrameCorrection> corrections;
    map::KeyFrameCorrection last;
    for (const map::KeyFrameId id : map_.keyFrameIds()) {
      SE3d T_w_b;
      map::KeyFrameId previous = map::kNoKeyFrame;
      map_.readKeyFrame(id, [&](const map::KeyFrame& kf) {
        T_w_b = kf.T_w_b;
        previous = kf.previous;
        last.t_ns = kf.t_ns;
      });
      const auto solved = blocks_.find(id);
      if (solved != blocks_.end()) {
        last.C = solved->second.fixed ? SE3d() : bodyPose(solved->second) * T_w_b.inverse();
        if (!solved->second.fixed) writeKeyFrame(id, solved->second);
      } else {
        const auto from = corrections.find(previous);
        if (from != corrections.end()) last.C = from->second.C;
        map_.setKeyFramePose(id, last.C * T_w_b);
        map_.rotateKeyFrameVelocity(id, last.C.rotation());
      }
      corrections[id] = last;
    }
    return corrections;
  }

  void recordCorrections(const std::map<map::KeyFrameId, map::KeyFrameCorrection>& corrections) {
    map::MapCorrection record;
    for (const auto& [id, correction] : corrections)
      record.keyframes.push_back(correction);
    std::stable_sort(record.keyframes.begin(), record.keyframes.end(),
                     [](const auto& x, const auto& y) { return x.t_ns < y.t_ns; });
    map_.recordCorrection(std::move(record));
  }

  /// Solved points take the solution, the others their oldest observer's correction. The solved
  /// points' normals and distances are updated by removeOutliers(), after it has removed their
  /// outlying observations.
  void movePoints(const std::map<map::KeyFrameId, map::KeyFrameCorrection>& corrections) {
    for (const map::MapPointId id : map_.mapPointIds()) {
      const auto solved = points_.find(id);
      if (solved != points_.end()) {
        map_.setMapPointPosition(id, solved->second);
        continue;
      }
      std::optional<std::pair<map::KeyFrameId, Eigen::Vector3d>> reference;
      map_.readMapPoint(id, [&](const map::MapPoint& p) {
        if (!p.observations.empty()) reference.emplace(p.observations.begin()->first, p.p_w);
      });
      if (!reference) continue;
      const auto it = corrections.find(reference->first);
      if (it != corrections.end())
        map_.setMapPointPosition(id, it->second.apply(reference->second));
      if (!map_.updateNormalAndDistances(id)) map_.eraseMapPoint(id);
    }
  }

  /// Erases the left observations that could not be evaluated at the initial state; returns how
  /// many were erased.
  int removeInvalidAtStart() {
    int removed = 0;
    std::set<map::MapPointId> touched;
    for (const BaObservation& o : invalid_at_start_) {
      if (!o.left) continue;
      if (map_.eraseObservation(o.point, o.keyframe)) ++removed;
      touched.insert(o.point);
    }
    for (const map::MapPointId id : touched) {
      if (!map_.updateNormalAndDistances(id)) map_.eraseMapPoint(id);
    }
    return removed;
  }

  int removeOutliers() {
    int removed = 0;
    for (const BaObservation& o : observations_) {
      if (!o.left) continue;
      const auto r = o.factor->residual(
          optim::fromPoseBlock(blocks_.at(o.keyframe).state.pose.data()), points_.at(o.point));
      if (!r || r->squaredNorm() > settings_.chi2_outlier) {
        if (map_.eraseObservation(o.point, o.keyframe)) ++removed;
      }
    }
    for (const auto& [id, p_w] : points_) {
      if (!map_.updateNormalAndDistances(id)) map_.eraseMapPoint(id);
    }
    return removed;
  }

  map::Map& map_;
  const BundleAdjustmentWindow window_;
  /// The right observations, while prepare() runs.
  const std::map<map::KeyFrameId, RightObservations>* right_ = nullptr;
  BundleAdjustmentSettings settings_;
  const std::optional<BundleAdjustmentImu> imu_;  ///< Its preintegrations: used by prepare() only.
  Stage stage_ = Stage::kNothing;
  BundleAdjustmentResult result_;
  std::vector<optim::ReprojectionCamera> cameras_;
  ceres::Problem::Options problem_options_;
  std::unique_ptr<ceres::Problem> problem_;
  std::map<map::KeyFrameId, map::KeyFrame> keyframes_;
  std::map<map::KeyFrameId, KeyFrameBlocks> blocks_;
  std::map<map::MapPointId, Eigen::Vector3d> points_;
  std::vector<BaObservation> observations_;
  std::vector<BaObservation> invalid_at_start_;  ///< Not in the problem: behind the camera.
};

}  // namespace detail

BundleAdjustmentWindow fullInertialWindow(const std::vector<map::KeyFrameId>& ids,
                                          double bias_prior_sigma_gyro,
                                          double bias_prior_sigma_acc) {
  BundleAdjustmentWindow window;
  window.inertial = true;
  window.optimised = ids;
  if (!ids.empty()) window.gauge = ids.front();
  window.bias_prior_sigma_gyro = bias_prior_sigma_gyro;
  window.bias_prior_sigma_acc = bias_prior_sigma_acc;
  return window;
}

BundleAdjustmentResult bundleAdjust(map::Map& map, const BundleAdjustmentWindow& window,
                                    const std::vector<optim::ReprojectionCamera>& cameras,
                                    const std::map<map::KeyFrameId, RightObservations>& right,
                                    const BundleAdjustmentSettings& settings,
                                    const std::optional<BundleAdjustmentImu>& imu) {
  detail::Problem problem(map, window, cameras, settings, imu);
  problem.prepare(right);
  problem.solve();
  return problem.write(false);
}

DeferredBundleAdjustment::DeferredBundleAdjustment(
    map::Map& map, const BundleAdjustmentWindow& window,
    const std::vector<optim::ReprojectionCamera>& cameras,
    const std::map<map::KeyFrameId, RightObservations>& right,
    const BundleAdjustmentSettings& settings, const std::optional<BundleAdjustmentImu>& imu)
    : problem_(std::make_unique<detail::Problem>(map, window, cameras, settings, imu)),
      generation_(map.correctionCount()) {
  const map::Map::ReadLock reading = map.readLock();  // a state no update is half-way through
  problem_->prepare(right);
}

DeferredBundleAdjustment::~DeferredBundleAdjustment() = default;

void DeferredBundleAdjustment::solve() {
  problem_->solve(&abort_);
}

BundleAdjustmentResult DeferredBundleAdjustment::apply() {
  return problem_->write(true);
}

}  // namespace superdyna::mapping
