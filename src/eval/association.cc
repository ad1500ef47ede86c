#include "superdyna/eval/association.h"

#include <fmt/format.h>

#include <algorithm>
#include <string>
#include <tuple>

#include "superdyna/core/error.h"

namespace superdyna::eval {
namespace {

struct Candidate {
  TimeNs abs_diff_ns;
  std::size_t gt_index;
  std::size_t est_index;

  /// Order of acceptance: smallest difference first; ties resolved deterministically.
  bool operator<(const Candidate& other) const {
    return std::tie(abs_diff_ns, gt_index, est_index) <
           std::tie(other.abs_diff_ns, other.gt_index, other.est_index);
  }
};

void requireIncreasing(const std::vector<TimeNs>& times_ns, const char* which) {
  for (std::size_t i = 1; i < times_ns.size(); ++i) {
    if (times_ns[i] <= times_ns[i - 1]) {
      throw InputError(fmt::format(
          "{} timestamps must increase strictly, but pose {} ({} s) is not "
          "later than pose {} ({} s)",
          which, i, formatNsAsSeconds(times_ns[i]), i - 1, formatNsAsSeconds(times_ns[i - 1])));
    }
  }
}

/// Every (gt, est) pair within max_diff. Both lists are sorted, so each estimate only looks at the
/// ground-truth window [t - max_diff, t + max_diff] (binary search) instead of all n * m pairs.
std::vector<Candidate> candidatePairs(const std::vector<TimeNs>& gt_times_ns,
                                      const std::vector<TimeNs>& est_times_ns,
                                      const AssociationOptions& options) {
  std::vector<Candidate> candidates;
  for (std::size_t e = 0; e < est_times_ns.size(); ++e) {
    const TimeNs t_ns = est_times_ns[e] + options.offset_ns;
    auto it = std::lower_bound(gt_times_ns.begin(), gt_times_ns.end(), t_ns - options.max_diff_ns);
    for (; it != gt_times_ns.end() && *it <= t_ns + options.max_diff_ns; ++it) {
      const TimeNs diff_ns = *it > t_ns ? *it - t_ns : t_ns - *it;
      candidates.push_back({diff_ns, static_cast<std::size_t>(it - gt_times_ns.begin()), e});
    }
  }
  return candidates;
}

}  // namespace

void AssociationOptions::validate() const {
  if (max_diff_ns < 0) {
    throw OptionError("max_diff_ns", fmt::format("must be >= 0, got {} ns", max_diff_ns));
  }
}

std::vector<IndexPair> associateTimestamps(const std::vector<TimeNs>& gt_times_ns,
                                           const std::vector<TimeNs>& est_times_ns,
                                           const AssociationOptions& options) {
  options.validate();
  requireIncreasing(gt_times_ns, "ground-truth");
  requireIncreasing(est_times_ns, "estimate");

  std::vector<Candidate> candidates = candidatePairs(gt_times_ns, est_times_ns, options);
  std::sort(candidates.begin(), candidates.end());

  std::vector<bool> gt_used(gt_times_ns.size(), false);
  std::vector<bool> est_used(est_times_ns.size(), false);
  std::vector<IndexPair> pairs;
  for (const Candidate& c : candidates) {
    if (gt_used[c.gt_index] || est_used[c.est_index]) continue;
    gt_used[c.gt_index] = true;
    est_used[c.est_index] = true;
    pairs.push_back({c.gt_index, c.est_index});
  }
  std::sort(pairs.begin(), pairs.end(),
            [](const IndexPair& a, const IndexPair& b) { return a.gt_index < b.gt_index; });
  return pairs;
}

AssociatedPoses associate(const Trajectory& gt, const Trajectory& est,
                          const AssociationOptions& options) {
  const auto times = [](const Trajectory& trajectory) {
    std::vector<TimeNs> t_ns;
    t_ns.reserve(trajectory.size());
    for (const StampedPose& pose : trajectory)
      t_ns.push_back(pose.t_ns);
    return t_ns;
  };
  AssociatedPoses matched;
  for (const IndexPair& pair : associateTimestamps(times(gt), times(est), options)) {
    matched.t_ns.push_back(gt[pair.gt_index].t_ns);
    matched.gt.push_back(gt[pair.gt_index].T_w_x);
    matched.est.push_back(est[pair.est_index].T_w_x);
  }
  return matched;
}

}  // namespace superdyna::eval
