#include "superdyna/eval/ate.h"

#include <fmt/format.h>

#include <numbers>

#include "superdyna/core/error.h"

namespace superdyna::eval {

namespace {
constexpr double kDegPerRad = 180.0 / std::numbers::pi;
}

AteResult computeAte(const std::vector<SE3d>& gt, const std::vector<SE3d>& est,
                     const Sim3d& alignment) {
  if (gt.size() != est.size()) {
    throw InputError(fmt::format("ATE needs associated poses, got {} ground-truth and {} estimated",
                                 gt.size(), est.size()));
  }
  AteResult ate;
  ate.trans_errors_m.reserve(gt.size());
  ate.rot_errors_deg.reserve(gt.size());
  for (std::size_t i = 0; i < gt.size(); ++i) {
    const SE3d aligned = alignment * est[i];
    ate.trans_errors_m.push_back((gt[i].t - aligned.t).norm());
    const Eigen::Matrix3d rotation_error = gt[i].rotation().transpose() * aligned.rotation();
    ate.rot_errors_deg.push_back(rotationAngle(rotation_error) * kDegPerRad);
  }
  ate.trans = computeStatistics(ate.trans_errors_m);
  ate.rot = computeStatistics(ate.rot_errors_deg);
  return ate;
}

}  // namespace superdyna::eval
