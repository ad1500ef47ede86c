#include "superdyna/mapping/local_mapper.h"

#include <ceres/ceres.h>

#include <algorithm>
#include <cmath>
#include <memory>
#include <set>

#include "superdyna/core/error.h"
#include "superdyna/optim/se3_manifold.h"

namespace superdyna::mapping {

void LocalMapperOptions::validate() const {
  if (window_keyframes < 2) throw OptionError("mapping.window_keyframes", "must be >= 2");
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
}

namespace {

/// One reprojection residual of the local BA, kept to classify it after solving.
struct BaObservation {
  map::MapPointId point = map::kNoMapPoint;
  map::KeyFrameId keyframe = map::kNoKeyFrame;
  std::shared_ptr<optim::ReprojectionFactor> factor;
  bool left = true;  ///< Right-camera residuals are not removed individually.
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

}  // namespace

LocalMapper::LocalMapper(const LocalMapperOptions& options,
                         std::vector<optim::ReprojectionCamera> cameras)
    : options_(options), cameras_(std::move(cameras)) {
  options_.validate();
  if (cameras_.empty()) throw OptionError("cameras", "the local mapper needs the left camera");
  if (options_.triangulate) {
    PointTriangulatorOptions triangulation = options_.triangulation;
    triangulation.sigma0_px = options_.sigma0_px;
    triangulation.scale_factor = options_.scale_factor;
    triangulator_.emplace(triangulation, cameras_.front());
  }
}

void LocalMapper::addKeyFrame(map::KeyFrameId id, RightObservations right,
                              const std::vector<map::MapPointId>& new_points) {
  right_[id] = std::move(right);
  for (const map::MapPointId point : new_points)
    recent_points_.emplace_back(point, id);
}

void LocalMapper::reset() {
  right_.clear();
  recent_points_.clear();
}

int LocalMapper::processKeyFrame(map::Map& map, map::KeyFrameId newest) {
  if (triangulator_) {
    for (const map::MapPointId point : triangulator_->createPoints(map, newest))
      recent_points_.emplace_back(point, newest);
  }
  const std::vector<map::KeyFrameId> window = localWindow(map, newest);
  const int used = window.size() >= 2 ? bundleAdjust(map, window) : 0;
  cullRecentPoints(map, newest);
  return used;
}

std::vector<map::KeyFrameId> LocalMapper::localWindow(const map::Map& map,
                                                      map::KeyFrameId newest) const {
  std::vector<map::KeyFrameId> window =
      map.bestCovisibleKeyFrames(newest, options_.window_keyframes - 1);
  window.push_back(newest);
  std::sort(window.begin(), window.end());
  return window;
}

int LocalMapper::bundleAdjust(map::Map& map, const std::vector<map::KeyFrameId>& window) {
  std::map<map::KeyFrameId, optim::PoseBlock> poses;
  std::map<map::KeyFrameId, map::KeyFrame> keyframes;
  std::map<map::MapPointId, int> counts;  // residuals per point
  for (const map::KeyFrameId id : window) {
    map.readKeyFrame(id, [&](const map::KeyFrame& kf) { keyframes.emplace(id, kf); });
    poses[id] = optim::toPoseBlock(keyframes.at(id).T_w_b);
  }
  for (const auto& [id, kf] : keyframes) {
    const auto& right = right_[id];
    for (std::size_t i = 0; i < kf.map_points.size(); ++i) {
      if (kf.map_points[i] == map::kNoMapPoint) continue;
      counts[kf.map_points[i]] += (i < right.size() && right[i]) ? 2 : 1;
    }
  }
  std::map<map::MapPointId, Eigen::Vector3d> points;
  for (const auto& [id, count] : counts) {
    if (count < 2) continue;
    if (const auto p = map.mapPointPosition(id)) points.emplace(id, *p);
  }

  ceres::Problem::Options problem_options;
  problem_options.cost_function_ownership = ceres::TAKE_OWNERSHIP;
  problem_options.manifold_ownership = ceres::TAKE_OWNERSHIP;
  ceres::Problem problem(problem_options);
  std::vector<BaObservation> observations;
  const auto add = [&](map::KeyFrameId kf_id, map::MapPointId point_id, int camera,
                       const Eigen::Vector2d& normalized, int octave) {
    const double sigma = optim::octaveSigmaPx(octave, options_.sigma0_px, options_.scale_factor);
    auto factor = std::make_shared<optim::ReprojectionFactor>(
        normalized, cameras_[static_cast<std::size_t>(camera)], sigma);
    problem.AddResidualBlock(new BorrowedFactor(factor.get()),
                             optim::newHuberLoss(options_.chi2_outlier), poses[kf_id].data(),
                             points[point_id].data());
    observations.push_back({point_id, kf_id, factor, camera == 0});
  };
  for (const auto& [id, kf] : keyframes) {
    const auto& right = right_[id];
    for (std::size_t i = 0; i < kf.map_points.size(); ++i) {
      const map::MapPointId point_id = kf.map_points[i];
      if (point_id == map::kNoMapPoint || !points.contains(point_id)) continue;
      add(id, point_id, 0, kf.keypoints[i].normalized, kf.keypoints[i].octave);
      if (cameras_.size() > 1 && i < right.size() && right[i]) {
        add(id, point_id, 1, *right[i], kf.keypoints[i].octave);
      }
    }
  }
  if (observations.empty()) return 0;
  for (auto& [id, block] : poses) {
    problem.SetManifold(block.data(), new optim::SE3Manifold());
  }
  problem.SetParameterBlockConstant(poses.begin()->second.data());

  ceres::Solver::Options solver;
  solver.linear_solver_type = ceres::DENSE_SCHUR;
  solver.max_num_iterations = options_.iterations;
  solver.num_threads = 1;
  solver.logging_type = ceres::SILENT;
  ceres::Solver::Summary summary;
  ceres::Solve(solver, &problem, &summary);

  for (const auto& [id, block] : poses)
    map.setKeyFramePose(id, optim::fromPoseBlock(block.data()));
  std::set<map::MapPointId> touched;
  for (const auto& [id, p_w] : points) {
    map.setMapPointPosition(id, p_w);
    touched.insert(id);
  }
  for (const BaObservation& o : observations) {
    if (!o.left) continue;
    const auto r =
        o.factor->residual(optim::fromPoseBlock(poses[o.keyframe].data()), points[o.point]);
    if (!r || r->squaredNorm() > options_.chi2_outlier) map.eraseObservation(o.point, o.keyframe);
  }
  for (const map::MapPointId id : touched) {
    if (!map.updateNormalAndDistances(id)) map.eraseMapPoint(id);
  }
  return static_cast<int>(observations.size());
}

void LocalMapper::cullRecentPoints(map::Map& map, map::KeyFrameId newest) {
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
