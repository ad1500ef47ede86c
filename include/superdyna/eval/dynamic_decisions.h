#pragma once
// Scoring the moving-object test (`superdyna run --dynamic-log`) against a simulated sequence's
// ground truth (mav0/instance_states.csv: per frame and agent whether it moves).
//
// Per object-frame (one row of the log): "moving" is the positive class. Rows with at least
// `min_pairs` matched features and a decision (moving or static) enter precision and recall;
// unverified rows are counted apart. The share of features kept on static movable objects counts
// every row whose agent stands still at that frame.
//
// False objects injected by the simulated segmenter errors (semantics.error_*,
// semantics/segmenter_errors.h) have ids from semantics::kInjectedObjectIdBase up, which the
// ground truth never lists: such a row is scored as a static object (its features lie on static
// structure, so dropping them loses static features and deciding it moving is a false moving),
// in `all`, in its class and in DecisionScore::injected. Other rows the ground truth does not list
// are counted as unknown and left out.

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "superdyna/core/time.h"

namespace superdyna::eval {

/// One row of a dynamic log (system/dynamic_log.h).
struct DecisionRow {
  TimeNs t_ns = 0;
  int instance_id = 0;
  std::string class_name;
  int pairs = 0;
  int tested = 0;
  std::string decision;  ///< moving | static | unverified
  int keypoints = 0;
  int dropped = 0;
};

/// Throws InputError naming file, line and field on a malformed row.
std::vector<DecisionRow> readDynamicLog(const std::filesystem::path& file);

/// (t_ns, instance id) -> moving, from instance_states.csv.
using InstanceStates = std::map<std::pair<TimeNs, int>, bool>;
InstanceStates readInstanceStates(const std::filesystem::path& file);

struct DecisionCounts {
  long true_moving = 0, false_moving = 0, missed_moving = 0, true_static = 0;
  long unverified = 0;  ///< Rows with enough pairs but no decision.
  long few_pairs = 0;   ///< Rows with fewer than min_pairs.
  long unknown = 0;     ///< Rows whose (t_ns, id) the ground truth does not list (not injected).
  long static_keypoints = 0, static_kept = 0;  ///< On objects that stand still.
  long moving_keypoints = 0, moving_dropped = 0;
  double precision() const;  ///< NaN without a moving decision.
  double recall() const;     ///< NaN without a moving object-frame.
  double staticKeptShare() const;
  double movingDroppedShare() const;
};

struct DecisionScore {
  DecisionCounts all;  ///< Every row the ground truth lists, and the injected false objects.
  std::map<std::string, DecisionCounts> by_class;
  DecisionCounts injected;  ///< The injected false objects alone (all static).
};

/// Whether a logged instance id is an injected false object's (semantics/segmenter_errors.h).
bool isInjectedObject(int instance_id);

DecisionScore scoreDecisions(const std::vector<DecisionRow>& rows, const InstanceStates& truth,
                             int min_pairs);

}  // namespace superdyna::eval
