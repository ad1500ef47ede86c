#pragma once

#include <memory>

#include "commands/command.h"

namespace superdyna::apps {

/// `superdyna simulate`: writes a synthetic dynamic-scene stereo + IMU sequence (EuRoC layout).
std::unique_ptr<Command> makeSimulateCommand(CLI::App& app);

}  // namespace superdyna::apps
