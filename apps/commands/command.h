#pragma once
// A subcommand of the `superdyna` tool: it declares its options on a CLI11 sub-app and runs once
// the command line is parsed. Library errors (InputError, OptionError) propagate to main().

#include <CLI/CLI.hpp>
#include <filesystem>
#include <string>
#include <vector>

namespace superdyna::apps {

class Command {
 public:
  virtual ~Command() = default;
  /// The CLI11 sub-app this command registered, to check whether it was chosen.
  virtual CLI::App* subcommand() const = 0;
  /// Runs the command; returns the process exit code.
  virtual int run() = 0;
};

/// Declares `--dataset euroc|kitti` (into `kind`) and the required `--path DIR` (into `path`), the
/// options of every command that reads a sequence.
inline void addDatasetOptions(CLI::App& sub, std::string& kind, std::filesystem::path& path,
                              bool bags = false) {
  std::vector<std::string> kinds = {"euroc", "kitti"};
  if (bags) kinds.push_back("rosbag");
  sub.add_option("--dataset", kind, "Dataset layout")
      ->check(CLI::IsMember(kinds))
      ->capture_default_str();
  CLI::Option* option =
      sub.add_option("--path", path,
                     bags ? "Sequence folder (EuRoC: the one holding mav0/), or the .bag file"
                          : "Sequence folder (EuRoC: the one holding mav0/)")
          ->required();
  if (bags) {
    option->check(CLI::ExistingPath);
  } else {
    option->check(CLI::ExistingDirectory);
  }
}

}  // namespace superdyna::apps
