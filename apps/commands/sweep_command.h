#pragma once

#include <memory>

#include "commands/command.h"

namespace superdyna::apps {

/// `superdyna sweep SPEC.yaml --out DIR`: sequences x configs x runs, scored into tables and an
/// HTML report; resumable; local, GNU parallel or Slurm dispatch.
std::unique_ptr<Command> makeSweepCommand(CLI::App& app);

}  // namespace superdyna::apps
