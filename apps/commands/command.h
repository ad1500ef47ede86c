#pragma once
// A subcommand of the `superdyna` tool: it declares its options on a CLI11 sub-app and runs once
// the command line is parsed. Library errors (InputError, OptionError) propagate to main().

#include <CLI/CLI.hpp>

namespace superdyna::apps {

class Command {
 public:
  virtual ~Command() = default;
  /// The CLI11 sub-app this command registered, to check whether it was chosen.
  virtual CLI::App* subcommand() const = 0;
  /// Runs the command; returns the process exit code.
  virtual int run() = 0;
};

}  // namespace superdyna::apps
