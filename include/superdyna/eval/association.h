#pragma once
// Pairing estimated poses with ground-truth poses by timestamp, as the TUM RGB-D benchmark's
// associate.py does: every (estimate, reference) pair within the tolerance is a candidate, and
// candidates are accepted greedily by increasing time difference, each pose used at most once.

#include <cstddef>
#include <vector>

#include "superdyna/core/time.h"
#include "superdyna/core/trajectory.h"

namespace superdyna::eval {

struct AssociationOptions {
  /// Largest accepted |t_est + offset - t_gt|, in nanoseconds (default 10 ms). Must be >= 0.
  TimeNs max_diff_ns = 10 * kNsPerMillisecond;
  /// Added to every estimate timestamp before matching, in nanoseconds (clock offset est -> gt).
  TimeNs offset_ns = 0;

  /// Throws OptionError naming the offending option.
  void validate() const;
};

/// One accepted match: indices into the ground-truth and the estimate trajectory.
struct IndexPair {
  std::size_t gt_index = 0;
  std::size_t est_index = 0;

  bool operator==(const IndexPair&) const = default;
};

/// Matches timestamps one-to-one, greedily by smallest |t_est + offset - t_gt| (ties: earlier
/// ground truth first, then earlier estimate), keeping only differences <= max_diff_ns.
/// Both time lists must be strictly increasing (InputError otherwise). The result is sorted by
/// ground-truth time.
std::vector<IndexPair> associateTimestamps(const std::vector<TimeNs>& gt_times_ns,
                                           const std::vector<TimeNs>& est_times_ns,
                                           const AssociationOptions& options);

/// The matched poses of two trajectories, in ground-truth time order; all vectors have one entry
/// per pair.
struct AssociatedPoses {
  std::vector<TimeNs> t_ns;  ///< Ground-truth timestamp of each pair.
  std::vector<SE3d> gt;      ///< T_w_x of the ground truth.
  std::vector<SE3d> est;     ///< T_w_x of the estimate, in its own world frame.

  std::size_t size() const { return t_ns.size(); }
};

/// Associates `est` with `gt` (see associateTimestamps) and gathers the matched poses.
AssociatedPoses associate(const Trajectory& gt, const Trajectory& est,
                          const AssociationOptions& options);

}  // namespace superdyna::eval
