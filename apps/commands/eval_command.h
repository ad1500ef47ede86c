#pragma once

#include <memory>

#include "commands/command.h"

namespace superdyna::apps {

/// `superdyna eval`: ATE / RPE of one or several estimates against ground truth.
std::unique_ptr<Command> makeEvalCommand(CLI::App& app);

}  // namespace superdyna::apps
