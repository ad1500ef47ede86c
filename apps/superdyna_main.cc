// The `superdyna` command line: one binary, one subcommand per job.

#include <spdlog/spdlog.h>

#include <CLI/CLI.hpp>
#include <memory>
#include <string>
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

/// Exit codes as --help documents them (kExitCodes): 0 success, 1 command-line usage error
/// (CLI11: an unknown option, a missing or invalid value, a path that does not exist), 2 bad input
/// or options, 3 unexpected internal error; `run` stopped by a signal: 128 + its number.
constexpr int kExitUsage = 1;
constexpr int kExitBadInput = 2;
constexpr int kExitInternal = 3;
constexpr const char* kExitCodes =
    "Exit codes: 0 ok, 1 usage error (unknown option, missing or invalid value, path not found), "
    "2 bad input or options (the message names the file, line or option), 3 internal error; "
    "run stopped by SIGINT or SIGTERM: 130 or 143, after writing its outputs.";

/// CLI11's own exit codes (105 for a failed check, 106 for a missing option, ...) are all usage
/// errors; --help and --version exit with 0.
int exitOnParseError(const CLI::App& app, const CLI::ParseError& error) {
  return app.exit(error) == 0 ? 0 : kExitUsage;
}

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
  std::vector<std::unique_ptr<superdyna::apps::Command>> commands;
  commands.push_back(superdyna::apps::makeEvalCommand(app));
  commands.push_back(superdyna::apps::makeEvalDynamicCommand(app));
  commands.push_back(superdyna::apps::makeSimulateCommand(app));
  commands.push_back(superdyna::apps::makeInfoCommand(app));
  commands.push_back(superdyna::apps::makeDemoCommand(app));
  commands.push_back(superdyna::apps::makeRunCommand(app));
  commands.push_back(superdyna::apps::makeSweepCommand(app));

  for (const auto& command : commands) {
    CLI::App* sub = command->subcommand();
    const std::string footer = sub->get_footer();
    sub->footer(footer.empty() ? std::string(kExitCodes) : footer + "\n" + kExitCodes);
  }
  // After the subcommands: CLI11 hands a parent's footer on to subcommands made after it.
  app.footer(std::string("Run 'superdyna <command> --help' for the options of one command.\n") +
             kExitCodes);

  try {
    app.parse(argc, argv);
  } catch (const CLI::ParseError& e) {
    return exitOnParseError(app, e);
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
