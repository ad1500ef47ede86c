#pragma once

#include <memory>

#include "commands/command.h"

namespace superdyna::apps {

/// `superdyna run`: runs SLAM over a dataset and writes the trajectory of every frame.
std::unique_ptr<Command> makeRunCommand(CLI::App& app);

}  // namespace superdyna::apps
