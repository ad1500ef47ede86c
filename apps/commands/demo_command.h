#pragma once

#include <memory>

#include "commands/command.h"

namespace superdyna::apps {

/// `superdyna demo`: the built-in default job (an evaluation demo until the SLAM pipeline lands).
std::unique_ptr<Command> makeDemoCommand(CLI::App& app);

}  // namespace superdyna::apps
