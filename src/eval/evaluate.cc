#include "superdyna/eval/evaluate.h"

#include <fmt/format.h>

#include <cmath>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/eval/ate.h"

namespace superdyna::eval {
namespace {

constexpr std::size_t kMinPairs = 3;  // fewest points that determine a rotation

std::string describeTimeRange(const Trajectory& trajectory, TimeNs offset_ns = 0) {
  if (trajectory.empty()) return "no poses";
  return fmt::format("{} poses from {:.3f} s to {:.3f} s", trajectory.size(),
                     nsToSeconds(trajectory.front().t_ns + offset_ns),
                     nsToSeconds(trajectory.back().t_ns + offset_ns));
}

[[noreturn]] void throwTooFewPairs(const Trajectory& gt, const Trajectory& est,
                                   const AssociationOptions& association, std::size_t pairs) {
  const std::string offset_note = association.offset_ns == 0
                                      ? std::string()
                                      : fmt::format(" (after adding the offset: {})",
                                                    describeTimeRange(est, association.offset_ns));
  throw InputError(fmt::format(
      "only {} pose pairs could be associated by time, at least {} are needed. Ground truth: {}. "
      "Estimate: {}{}. Check that both use the same clock and units, or adjust --max-diff (now "
      "{} ms) or --offset (now {} ms)",
      pairs, kMinPairs, describeTimeRange(gt), describeTimeRange(est), offset_note,
      static_cast<double>(association.max_diff_ns) / kNsPerMillisecond,
      static_cast<double>(association.offset_ns) / kNsPerMillisecond));
}

Eigen::Matrix3Xd positionsOf(const std::vector<SE3d>& poses) {
  Eigen::Matrix3Xd positions(3, static_cast<Eigen::Index>(poses.size()));
  for (std::size_t i = 0; i < poses.size(); ++i) {
    positions.col(static_cast<Eigen::Index>(i)) = poses[i].t;
  }
  return positions;
}

/// The uncertainty of an estimated rotation (EvaluationResult::alignment_rotation_uncertainty_deg)
/// over the pairs it was estimated on.
double alignmentRotationUncertaintyDeg(const Eigen::Matrix3Xd& gt_positions,
                                       const std::vector<double>& trans_errors_m,
                                       const EvaluationOptions& options) {
  if (options.given_alignment || options.align == AlignmentMode::kNone) return 0.0;
  const Eigen::Index used = options.align_first_n > 0 && options.align_first_n < gt_positions.cols()
                                ? options.align_first_n
                                : gt_positions.cols();
  double squared = 0.0;
  for (Eigen::Index i = 0; i < used; ++i)
    squared +=
        trans_errors_m[static_cast<std::size_t>(i)] * trans_errors_m[static_cast<std::size_t>(i)];
  const double rms = std::sqrt(squared / static_cast<double>(used));
  return rotationUncertaintyDeg(gt_positions.leftCols(used), rms);
}

std::vector<PoseError> perPoseErrors(const AssociatedPoses& matched, const Sim3d& alignment,
                                     const AteResult& ate) {
  std::vector<PoseError> poses(matched.size());
  for (std::size_t i = 0; i < matched.size(); ++i) {
    poses[i].t_ns = matched.t_ns[i];
    poses[i].gt_position = matched.gt[i].t;
    poses[i].aligned_position = alignment * matched.est[i].t;
    poses[i].trans_error_m = ate.trans_errors_m[i];
    poses[i].rot_error_deg = ate.rot_errors_deg[i];
  }
  return poses;
}

}  // namespace

void EvaluationOptions::validate() const {
  association.validate();
  rpe.validate();
  if (align != AlignmentMode::kNone && align_first_n > 0 &&
      align_first_n < static_cast<int>(kMinPairs)) {
    throw OptionError("align_first_n",
                      fmt::format("must be <= 0 (all poses) or >= {} to determine an alignment, "
                                  "got {}",
                                  kMinPairs, align_first_n));
  }
}

EvaluationResult evaluate(const Trajectory& gt, const Trajectory& est,
                          const EvaluationOptions& options) {
  options.validate();
  const AssociatedPoses matched = associate(gt, est, options.association);
  if (matched.size() < kMinPairs) throwTooFewPairs(gt, est, options.association, matched.size());

  EvaluationResult result;
  result.gt_poses = gt.size();
  result.est_poses = est.size();
  result.pairs = matched.size();
  result.align = options.align;
  result.align_first_n = options.align_first_n;
  result.alignment_given = options.given_alignment.has_value();
  result.alignment = options.given_alignment
                         ? *options.given_alignment
                         : alignPositions(positionsOf(matched.est), positionsOf(matched.gt),
                                          options.align, options.align_first_n);

  const AteResult ate = computeAte(matched.gt, matched.est, result.alignment);
  result.ate_trans = ate.trans;
  result.ate_rot = ate.rot;
  result.alignment_rotation_uncertainty_deg =
      alignmentRotationUncertaintyDeg(positionsOf(matched.gt), ate.trans_errors_m, options);

  // RPE is invariant to a rigid alignment, but a scale estimated by Sim(3) must be applied.
  const double rpe_scale = options.align == AlignmentMode::kSim3 ? result.alignment.s : 1.0;
  result.rpe_options = options.rpe;
  try {
    const RpeResult rpe = computeRpe(matched.gt, matched.est, rpe_scale, options.rpe);
    result.rpe_trans = rpe.trans;
    result.rpe_rot = rpe.rot;
  } catch (const InputError& e) {
    if (options.require_rpe) throw;
    result.rpe_missing = e.what();  // a path shorter than the delta: ATE still holds
  }

  result.poses = perPoseErrors(matched, result.alignment, ate);
  return result;
}

}  // namespace superdyna::eval
