#pragma once
// Least-squares alignment of an estimated trajectory to the ground truth (Umeyama 1991, "Least-
// squares estimation of transformation parameters between two point patterns"), as used by evo and
// the TUM RGB-D benchmark before computing the absolute trajectory error. Monocular systems are
// aligned with Sim(3) (their scale is unobservable), stereo and visual-inertial ones with SE(3).

#include <Eigen/Core>
#include <string>

#include "superdyna/core/geometry.h"

namespace superdyna::eval {

enum class AlignmentMode {
  kNone,  ///< Compare in the estimate's own frame (identity alignment).
  kSE3,   ///< Rotation and translation, scale fixed to 1.
  kSim3,  ///< Rotation, translation and scale.
};

/// "none", "se3", "sim3" (case-insensitive) -> mode; throws OptionError otherwise.
AlignmentMode parseAlignmentMode(const std::string& name);
/// "none", "se3" or "sim3".
std::string toString(AlignmentMode mode);

/// The similarity (scale s, rotation R, translation t) minimising sum_i ||dst_i - (s R src_i +
/// t)||^2 over the columns of `src` and `dst` (positions in metres). With `with_scale` false, s
/// = 1. Throws InputError for fewer than 3 points, different point counts, coincident points or
/// points on one line (the rotation about that line is then undetermined).
Sim3d umeyamaAlignment(const Eigen::Matrix3Xd& src, const Eigen::Matrix3Xd& dst, bool with_scale);

/// How far (degrees) an alignment's rotation fitted to `positions` (metres, one per column) is
/// uncertain when the fit leaves `residual_rms_m` of error: the angle that residual subtends at the
/// points' lever arm about their worst-determined axis, the principal axis of largest extent
/// (rotating about it moves them only by their spread across it: sqrt(e1^2 + e2^2) for principal
/// standard deviations e0 >= e1 >= e2). 90 for coincident points.
double rotationUncertaintyDeg(const Eigen::Matrix3Xd& positions, double residual_rms_m);

/// Aligns estimate positions to ground-truth positions (one column per associated pose) with
/// `mode`, using only the first `first_n` pairs when 0 < first_n < count (first_n <= 0: all).
/// The result maps the estimate frame into the ground-truth frame: p_gt ~ T * p_est.
Sim3d alignPositions(const Eigen::Matrix3Xd& est_positions, const Eigen::Matrix3Xd& gt_positions,
                     AlignmentMode mode, int first_n = 0);

}  // namespace superdyna::eval
