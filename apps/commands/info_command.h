#pragma once

#include <memory>

#include "commands/command.h"

namespace superdyna::apps {

/// `superdyna info`: reads and validates a dataset folder and summarises its streams.
std::unique_ptr<Command> makeInfoCommand(CLI::App& app);

}  // namespace superdyna::apps
