#pragma once
// Absolute trajectory error (Sturm et al. 2012, TUM RGB-D benchmark): the distance between each
// ground-truth position and the aligned estimated position of the same instant.

#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/eval/statistics.h"

namespace superdyna::eval {

struct AteResult {
  std::vector<double> trans_errors_m;  ///< ||p_gt - (s R p_est + t)|| per pose, metres.
  std::vector<double> rot_errors_deg;  ///< Angle of R_gt^T (R R_est) per pose, degrees.
  ErrorStatistics trans;               ///< Statistics of trans_errors_m [m].
  ErrorStatistics rot;                 ///< Statistics of rot_errors_deg [deg].
};

/// ATE of associated poses (gt[i] and est[i] belong to the same instant) after applying
/// `alignment` (estimate frame -> ground-truth frame) to the estimate. Throws InputError if the
/// sizes differ or there are no poses.
AteResult computeAte(const std::vector<SE3d>& gt, const std::vector<SE3d>& est,
                     const Sim3d& alignment);

}  // namespace superdyna::eval
