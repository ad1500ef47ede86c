#include "commands/eval_dynamic_command.h"

#include <fmt/format.h>

#include <cmath>
#include <filesystem>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/eval/dynamic_decisions.h"

namespace superdyna::apps {

namespace fs = std::filesystem;

namespace {

std::string percent(double share) {
  return std::isnan(share) ? std::string("-") : fmt::format("{:.1f} %", 100.0 * share);
}

void printRow(const std::string& name, const eval::DecisionCounts& c) {
  fmt::print("| {} | {} | {} | {} | {} | {} | {} | {} | {} | {} |\n", name,
             c.true_moving + c.false_moving + c.missed_moving + c.true_static, c.true_moving,
             c.false_moving, c.missed_moving, c.unverified, percent(c.precision()),
             percent(c.recall()), percent(c.staticKeptShare()), percent(c.movingDroppedShare()));
}

class EvalDynamicCommand : public Command {
 public:
  explicit EvalDynamicCommand(CLI::App& app) {
    sub_ = app.add_subcommand(
        "eval-dynamic",
        "Score moving-object decisions (superdyna run --dynamic-log) against a simulated "
        "sequence's ground truth (mav0/instance_states.csv): per object-frame precision and "
        "recall of 'moving', and the share of features kept on static movable objects; false "
        "objects injected by semantics.error_false_objects_per_frame (ids from 32768 up) count "
        "as static objects");
    sub_->add_option("--log", log_, "The run's --dynamic-log CSV")
        ->required()
        ->check(CLI::ExistingFile);
    sub_->add_option("--path", path_, "The simulated sequence (the folder holding mav0/)")
        ->required()
        ->check(CLI::ExistingDirectory);
    sub_->add_option("--min-pairs", min_pairs_,
                     "Object-frames with fewer matched features are left out of precision and "
                     "recall")
        ->check(CLI::NonNegativeNumber)
        ->capture_default_str();
  }

  CLI::App* subcommand() const override { return sub_; }

  int run() override {
    const fs::path states = path_ / "mav0" / "instance_states.csv";
    if (!fs::exists(states)) {
      throw OptionError("--path", fmt::format("'{}' has no ground-truth instance states ({})",
                                              path_.string(), states.string()));
    }
    const eval::DecisionScore score = eval::scoreDecisions(
        eval::readDynamicLog(log_), eval::readInstanceStates(states), min_pairs_);
    fmt::print("moving-object decisions of {} against {} (object-frames with >= {} pairs)\n",
               log_.string(), states.string(), min_pairs_);
    fmt::print(
        "| class | decided | moving ok | false moving | missed moving | unverified | precision | "
        "recall | static features kept | moving features dropped |\n");
    fmt::print("|---|---|---|---|---|---|---|---|---|---|\n");
    for (const auto& [name, counts] : score.by_class)
      printRow(name, counts);
    printRow("all", score.all);
    const eval::DecisionCounts& injected = score.injected;
    if (injected.few_pairs + injected.unverified + injected.true_static + injected.false_moving > 0)
      printRow("injected false objects (in all, static)", injected);
    fmt::print("object-frames with fewer pairs: {}; not in the ground truth: {}\n",
               score.all.few_pairs, score.all.unknown);
    return 0;
  }

 private:
  CLI::App* sub_ = nullptr;
  fs::path log_;
  fs::path path_;
  int min_pairs_ = 8;
};

}  // namespace

std::unique_ptr<Command> makeEvalDynamicCommand(CLI::App& app) {
  return std::make_unique<EvalDynamicCommand>(app);
}

}  // namespace superdyna::apps
