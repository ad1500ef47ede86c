// libFuzzer target: the CSV files of a EuRoC sequence (camera image lists, IMU samples, ground
// truth, instance classes), read by io::EurocDataset::open. The first input byte chooses the file
// the rest of the input replaces; the other files are small valid ones (euroc_files.h).

#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "euroc_files.h"
#include "fuzz_support.h"
#include "superdyna/io/euroc_dataset.h"

namespace superdyna::fuzz {
namespace {

namespace fs = std::filesystem;

/// The CSV files under mav0/ with their valid contents, in selector order.
FileSet csvFiles(const fs::path& mav0) {
  return FileSet({{mav0 / "cam0" / "data.csv", kCameraCsv},
                  {mav0 / "cam1" / "data.csv", kCameraCsv},
                  {mav0 / "imu0" / "data.csv", kImuCsv},
                  {mav0 / "state_groundtruth_estimate0" / "data.csv", kGroundTruthCsv},
                  {mav0 / "instances.csv", kInstancesCsv}});
}

/// The sequence's fixed files: sensor.yaml files, images (only checked to exist), mask folder.
fs::path makeSequence() {
  const fs::path mav0 = scratch() / "mav0";
  for (const char* camera : {"cam0", "cam1"}) {
    writeFile(mav0 / camera / "sensor.yaml", kCameraSensorYaml);
    for (const char* image : {"1.png", "2.png"})
      writeFile(mav0 / camera / "data" / image, "");
  }
  fs::create_directories(mav0 / "cam0" / "mask");
  writeFile(mav0 / "imu0" / "sensor.yaml", kImuSensorYaml);
  return mav0;
}

}  // namespace
}  // namespace superdyna::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace superdyna::fuzz;
  static const std::filesystem::path mav0 = makeSequence();
  static FileSet files = csvFiles(mav0);
  const SelectedInput input = selectInput(data, size);
  files.replace(input.selector % files.size(), input.rest);
  expectOnlyInputErrors([&] { superdyna::io::EurocDataset::open(mav0.parent_path()); });
  return 0;
}
