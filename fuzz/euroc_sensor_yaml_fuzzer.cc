// libFuzzer target: EuRoC sensor.yaml calibration files, read by io::readCameraCalibration
// (selector byte even) and io::readImuCalibration (odd). The rest of the input is the file.

#include <cstddef>
#include <cstdint>
#include <filesystem>

#include "fuzz_support.h"
#include "superdyna/io/calibration.h"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace superdyna::fuzz;
  static const std::filesystem::path file = scratch() / "cam0" / "sensor.yaml";
  const SelectedInput input = selectInput(data, size);
  writeFile(file, input.rest);
  expectOnlyInputErrors([&] {
    if (input.selector % 2 == 0) {
      const superdyna::sensors::CameraCalibration calibration =
          superdyna::io::readCameraCalibration(file);
      (void)calibration.cameraModel();  // the calibration must make a camera model
    } else {
      const superdyna::sensors::ImuCalibration calibration =
          superdyna::io::readImuCalibration(file);
      (void)calibration.periodNs();
    }
  });
  return 0;
}
