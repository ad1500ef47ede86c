// The `superdyna` command line: one binary, one subcommand per job.

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <memory>
#include <vector>

#include "commands/command.h"
#include "commands/demo_command.h"
#include "commands/eval_command.h"
#include "commands/eval_dynamic_command.h"
#include "commands/info_command.h"
#include "commands/run_command.h"
#include "commands/simulate_command.h"
#include "commands/sweep_command.h"
#include "superdyna/core/error.h"

namespace {

/// Exit codes: 0 success, 1 command-line usage error (CLI11), 2 bad input or options,
/// 3 unexpected internal error.
constexpr int kExitBadInput = 2;
constexpr int kExitInternal = 3;

int runChosen(const std::vector<std::unique_ptr<superdyna::apps::Command>>& commands) {
  for (const auto& command : commands) {
    if (command->subcommand()->parsed()) return command->run();
  }
  return 0;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app{"SuperDynaSLAM: visual-inertial SLAM for dynamic scenes, and its evaluation tools",
               "superdyna"};
  app.set_version_flag("--version", std::string(SUPERDYNA_VERSION));
  app.require_subcommand(1);
  app.footer("Run 'superdyna <command> --help' for the options of one command.");

  std::vector<std::unique_ptr<superdyna::apps::Command>> commands;
  commands.push_back(superdyna::apps::makeEvalCommand(app));
  commands.push_back(superdyna::apps::makeEvalDynamicCommand(app));
  commands.push_back(superdyna::apps::makeSimulateCommand(app));
  commands.push_back(superdyna::apps::makeInfoCommand(app));
  commands.push_back(superdyna::apps::makeDemoCommand(app));
  commands.push_back(superdyna::apps::makeRunCommand(app));
  commands.push_back(superdyna::apps::makeSweepCommand(app));

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return app.exit(e);
  }
  try {
    return runChosen(commands);
  } catch (const superdyna::InputError& e) {
    spdlog::error("{}", e.what());
    return kExitBadInput;
  } catch (const superdyna::OptionError& e) {
    spdlog::error("{}", e.what());
    return kExitBadInput;
  } catch (const std::exception& e) {
    spdlog::error("internal error: {}", e.what());
    return kExitInternal;
  }
}
