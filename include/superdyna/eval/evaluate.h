#pragma once
// One call that evaluates an estimated trajectory against ground truth the way the SLAM literature
// reports it: associate by time, align (Umeyama), then ATE and RPE.

#include <cstddef>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/core/trajectory.h"
#include "superdyna/eval/alignment.h"
#include "superdyna/eval/association.h"
#include "superdyna/eval/rpe.h"
#include "superdyna/eval/statistics.h"

namespace superdyna::eval {

/// An estimated alignment whose rotation is uncertain by more than this (degrees,
/// eval::rotationUncertaintyDeg) is not determined by the path: its rotation ATE means nothing.
constexpr double kUndeterminedRotationDeg = 10.0;

struct EvaluationOptions {
  AlignmentMode align = AlignmentMode::kSE3;
  /// Align with only the first N associated poses (N <= 0: all). Errors use every pose.
  int align_first_n = 0;
  /// A given alignment (estimate frame -> ground-truth frame), applied unchanged instead of one
  /// estimated with `align` (e.g. the alignment of another run of the same world: both ground
  /// truths share the world frame). `align` still says whether the RPE is scaled (sim3).
  std::optional<Sim3d> given_alignment;
  AssociationOptions association;
  RpeOptions rpe;
  /// Without a pose pair `rpe.delta` apart, throw (true), or report the ATE with the RPE left
  /// out (EvaluationResult::rpe_missing; superdyna sweep on paths shorter than the delta).
  bool require_rpe = true;

  /// Throws OptionError naming the offending option.
  void validate() const;
};

/// Errors of one associated pose, for plots and per-pose output.
struct PoseError {
  TimeNs t_ns = 0;                                             ///< Ground-truth timestamp.
  Eigen::Vector3d gt_position = Eigen::Vector3d::Zero();       ///< Metres, ground-truth frame.
  Eigen::Vector3d aligned_position = Eigen::Vector3d::Zero();  ///< Aligned estimate [m].
  double trans_error_m = 0.0;                                  ///< ATE of this pose [m].
  double rot_error_deg = 0.0;                                  ///< Rotation ATE of this pose [deg].
};

struct EvaluationResult {
  std::size_t gt_poses = 0;   ///< Poses in the ground-truth trajectory.
  std::size_t est_poses = 0;  ///< Poses in the estimated trajectory.
  std::size_t pairs = 0;      ///< Associated pose pairs (all ATE statistics use these).

  AlignmentMode align = AlignmentMode::kSE3;
  int align_first_n = 0;
  Sim3d alignment;               ///< Maps the estimate frame into the ground-truth frame.
  bool alignment_given = false;  ///< EvaluationOptions::given_alignment, not estimated.
  double scale() const { return alignment.s; }
  /// How far the estimated alignment's rotation is uncertain [deg] (rotationUncertaintyDeg of the
  /// aligned ground-truth positions and the ATE RMSE over them); 0 when no rotation was estimated
  /// (align none, or a given alignment).
  double alignment_rotation_uncertainty_deg = 0.0;
  /// The path does not determine the estimated alignment's rotation (a path of a few centimetres,
  /// or a nearly straight line, against errors of millimetres): ATE rot and the aligned
  /// orientations are not meaningful.
  bool alignmentRotationUndetermined() const {
    return alignment_rotation_uncertainty_deg > kUndeterminedRotationDeg;
  }

  ErrorStatistics ate_trans;  ///< [m]
  ErrorStatistics ate_rot;    ///< [deg]

  ErrorStatistics rpe_trans;  ///< [m/m] for a delta in metres, [m] for frames.
  ErrorStatistics rpe_rot;    ///< [deg/m] for a delta in metres, [deg] for frames.
  RpeOptions rpe_options;     ///< Delta and unit the RPE was computed with.
  std::string rpe_missing;    ///< Why no RPE was computed (require_rpe false); empty if it was.

  std::vector<PoseError> poses;  ///< One entry per associated pair, in time order.
};

/// Associates, aligns and measures `est` against `gt`. Throws OptionError for invalid options and
/// InputError when fewer than 3 poses associate (the message gives both trajectories' pose counts
/// and time ranges and suggests --max-diff / --offset), when the alignment is degenerate, or when
/// no RPE pair exists.
EvaluationResult evaluate(const Trajectory& gt, const Trajectory& est,
                          const EvaluationOptions& options);

}  // namespace superdyna::eval
