#pragma once

#include <memory>

#include "commands/command.h"

namespace superdyna::apps {

/// `superdyna demo`: a SLAM-free demo of the evaluation tool (the quick start runs SLAM itself).
std::unique_ptr<Command> makeDemoCommand(CLI::App& app);

}  // namespace superdyna::apps
