// libFuzzer target: trajectory files (TUM, EuRoC, KITTI with or without a times file, OpenLORIS
// segments) read by io::readTrajectory, and KITTI times files read by io::readTimesFile. The
// first input byte chooses the format and options, the rest is the file.

#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "fuzz_support.h"
#include "superdyna/io/trajectory_io.h"

namespace superdyna::fuzz {
namespace {

namespace fs = std::filesystem;

constexpr const char* kTimes = "0.0\n0.1\n0.2\n";

/// Selector bits 0-1: format (auto, tum, euroc, kitti); bit 2: TUM segment / KITTI times file;
/// bit 3: the input is a times file instead; bits 4-7: the TUM segment number.
void readWithSelector(std::uint8_t selector, const fs::path& file, const fs::path& times) {
  if (selector & 8) {
    (void)io::readTimesFile(file);
    return;
  }
  static constexpr io::TrajectoryFormat kFormats[] = {
      io::TrajectoryFormat::kAuto, io::TrajectoryFormat::kTum, io::TrajectoryFormat::kEuroc,
      io::TrajectoryFormat::kKitti};
  io::TrajectoryReadOptions options;
  options.format = kFormats[selector % 4];
  if (selector & 4) {
    if (options.format == io::TrajectoryFormat::kKitti) options.kitti_times = times;
    if (options.format == io::TrajectoryFormat::kTum) options.segment = selector >> 4;
  }
  (void)io::readTrajectory(file, options);
}

}  // namespace
}  // namespace superdyna::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace superdyna::fuzz;
  static const std::filesystem::path file = scratch() / "trajectory.txt";
  static const std::filesystem::path times = scratch() / "times.txt";
  static const bool times_written = (writeFile(times, kTimes), true);
  (void)times_written;
  const SelectedInput input = selectInput(data, size);
  writeFile(file, input.rest);
  expectOnlyInputErrors([&] { readWithSelector(input.selector, file, times); });
  return 0;
}
