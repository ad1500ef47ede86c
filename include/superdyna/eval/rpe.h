#pragma once
// Relative pose error (Sturm et al. 2012; KITTI odometry devkit): the error of the motion between
// two instants, independent of the drift accumulated before them. For pose pairs (i, j):
//   E_ij = (G_i^-1 G_j)^-1 (P_i^-1 P_j)
// with G the ground truth and P the estimate (positions scaled by the Sim(3) alignment scale when
// the scale was estimated). Translational error ||trans(E)||, rotational error angle(E).

#include <cstddef>
#include <string>
#include <utility>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/eval/statistics.h"

namespace superdyna::eval {

enum class DeltaUnit {
  kMeters,  ///< j is the first pose at least `delta` metres further along the ground-truth path.
  kFrames,  ///< j = i + delta.
};

/// "m" (also "meters", "metres") or "frames" (also "f") -> unit; throws OptionError otherwise.
DeltaUnit parseDeltaUnit(const std::string& name);
/// "m" or "frames".
std::string toString(DeltaUnit unit);

struct RpeOptions {
  double delta = 1.0;  ///< Pair distance, in `unit` (metres or frames).
  DeltaUnit unit = DeltaUnit::kMeters;

  /// Throws OptionError: delta must be finite and > 0, and a whole number >= 1 for frames.
  void validate() const;
};

/// Unit of the reported translational error: "m/m" (normalised by delta) for metres, "m" for
/// frames.
std::string rpeTransUnit(DeltaUnit unit);
/// Unit of the reported rotational error: "deg/m" for metres, "deg" for frames.
std::string rpeRotUnit(DeltaUnit unit);

/// The (i, j) pairs: every i for which a j exists. For metres, j is the first index with
/// pathLength(gt[i..j]) >= delta (a 1e-9 m tolerance absorbs the rounding of the summed path).
std::vector<std::pair<std::size_t, std::size_t>> rpePosePairs(const std::vector<SE3d>& gt,
                                                              const RpeOptions& options);

struct RpeResult {
  std::vector<std::pair<std::size_t, std::size_t>> pairs;  ///< (i, j) of every error below.
  std::vector<double> trans_errors;                        ///< Per pair, in rpeTransUnit(unit).
  std::vector<double> rot_errors;                          ///< Per pair, in rpeRotUnit(unit).
  ErrorStatistics trans;  ///< Statistics of trans_errors; trans.rmse is "RPEt".
  ErrorStatistics rot;    ///< Statistics of rot_errors; rot.rmse is "RPEr".
  double delta = 1.0;
  DeltaUnit unit = DeltaUnit::kMeters;
};

/// RPE of associated poses (gt[i] and est[i] belong to the same instant). `est_scale` multiplies
/// the estimated positions (the Sim(3) alignment scale, else 1). With metres, errors are divided by
/// delta (m/m, deg/m, as KITTI normalises by the nominal segment length). Throws InputError if the
/// sizes differ or no pair exists (trajectory shorter than delta), OptionError for bad options.
RpeResult computeRpe(const std::vector<SE3d>& gt, const std::vector<SE3d>& est, double est_scale,
                     const RpeOptions& options);

}  // namespace superdyna::eval
