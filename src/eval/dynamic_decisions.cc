#include "superdyna/eval/dynamic_decisions.h"

#include <cmath>
#include <limits>
#include <string_view>

#include "superdyna/core/error.h"
#include "superdyna/io/text_table.h"
#include "superdyna/semantics/segmenter_error_options.h"

namespace superdyna::eval {

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

int parseCount(std::string_view field, const InputLocation& where) {
  const double value = io::parseFiniteDouble(field, where);
  if (value < 0.0 || value != std::round(value) || value > 1e9) {
    throw InputError(where, "expected a non-negative integer");
  }
  return static_cast<int>(value);
}

double ratio(long numerator, long denominator) {
  return denominator > 0 ? static_cast<double>(numerator) / static_cast<double>(denominator) : kNaN;
}

DecisionRow parseDecisionRow(const io::TextRow& row, const std::filesystem::path& file) {
  io::requireFieldCount(row, file, 10, 10);
  const auto& f = row.fields;
  DecisionRow out;
  out.t_ns = io::parseIntegerNs(f[0], row.at(file, "t_ns"));
  out.instance_id = parseCount(f[1], row.at(file, "instance_id"));
  out.class_name = f[2];
  out.pairs = parseCount(f[3], row.at(file, "pairs"));
  out.tested = parseCount(f[4], row.at(file, "tested"));
  out.decision = f[7];
  if (out.decision != "moving" && out.decision != "static" && out.decision != "unverified") {
    throw InputError(row.at(file, "decision"), "expected moving, static or unverified");
  }
  out.keypoints = parseCount(f[8], row.at(file, "keypoints"));
  out.dropped = parseCount(f[9], row.at(file, "dropped"));
  if (out.dropped > out.keypoints) {
    throw InputError(row.at(file, "dropped"), "more than the object's keypoints");
  }
  return out;
}

void count(const DecisionRow& row, bool moving, int min_pairs, DecisionCounts& counts) {
  if (moving) {
    counts.moving_keypoints += row.keypoints;
    counts.moving_dropped += row.dropped;
  } else {
    counts.static_keypoints += row.keypoints;
    counts.static_kept += row.keypoints - row.dropped;
  }
  if (row.pairs < min_pairs) {
    ++counts.few_pairs;
  } else if (row.decision == "unverified") {
    ++counts.unverified;
  } else {
    const bool said_moving = row.decision == "moving";
    if (said_moving && moving) ++counts.true_moving;
    if (said_moving && !moving) ++counts.false_moving;
    if (!said_moving && moving) ++counts.missed_moving;
    if (!said_moving && !moving) ++counts.true_static;
  }
}

}  // namespace

double DecisionCounts::precision() const {
  return ratio(true_moving, true_moving + false_moving);
}
double DecisionCounts::recall() const {
  return ratio(true_moving, true_moving + missed_moving);
}
double DecisionCounts::staticKeptShare() const {
  return ratio(static_kept, static_keypoints);
}
double DecisionCounts::movingDroppedShare() const {
  return ratio(moving_dropped, moving_keypoints);
}

std::vector<DecisionRow> readDynamicLog(const std::filesystem::path& file) {
  std::vector<DecisionRow> rows;
  for (const io::TextRow& row : io::readTextRows(file, io::Delimiter::kComma)) {
    if (!row.fields.empty() && row.fields[0] == "t_ns") continue;  // the header
    rows.push_back(parseDecisionRow(row, file));
  }
  return rows;
}

InstanceStates readInstanceStates(const std::filesystem::path& file) {
  InstanceStates states;
  for (const io::TextRow& row : io::readTextRows(file, io::Delimiter::kComma)) {
    io::requireFieldCount(row, file, 3);
    const TimeNs t_ns = io::parseIntegerNs(row.fields[0], row.at(file, "t_ns"));
    const int id = parseCount(row.fields[1], row.at(file, "id"));
    const int moving = parseCount(row.fields[2], row.at(file, "moving"));
    if (moving > 1) throw InputError(row.at(file, "moving"), "expected 0 or 1");
    states[{t_ns, id}] = moving == 1;
  }
  return states;
}

bool isInjectedObject(int instance_id) {
  return instance_id >= semantics::kInjectedObjectIdBase &&
         instance_id <= semantics::kInjectedObjectIdLast;
}

DecisionScore scoreDecisions(const std::vector<DecisionRow>& rows, const InstanceStates& truth,
                             int min_pairs) {
  DecisionScore score;
  for (const DecisionRow& row : rows) {
    const auto found = truth.find({row.t_ns, row.instance_id});
    const bool injected = found == truth.end() && isInjectedObject(row.instance_id);
    if (found == truth.end() && !injected) {
      ++score.all.unknown;
      continue;
    }
    const bool moving = injected ? false : found->second;  // false objects are static structure
    count(row, moving, min_pairs, score.all);
    count(row, moving, min_pairs, score.by_class[row.class_name]);
    if (injected) count(row, moving, min_pairs, score.injected);
  }
  return score;
}

}  // namespace superdyna::eval
