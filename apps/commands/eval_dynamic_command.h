#pragma once

#include <memory>

#include "commands/command.h"

namespace superdyna::apps {

/// `superdyna eval-dynamic`: scores a run's moving-object decisions (--dynamic-log) against a
/// simulated sequence's instance_states.csv.
std::unique_ptr<Command> makeEvalDynamicCommand(CLI::App& app);

}  // namespace superdyna::apps
