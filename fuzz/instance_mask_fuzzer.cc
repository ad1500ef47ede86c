// libFuzzer target: 16-bit instance-mask images of a EuRoC sequence (mav0/cam0/mask/<image>),
// read by io::EurocDataset::loadInstanceMask against the classes of mav0/instances.csv.
// Selector bit 0 clear: the rest of the input is the mask file. Set: the rest gives a small id
// image (image_input.h), written as a 16-bit PNG; bit 1 then asks for the calibrated 8x6 size
// instead of the image's own.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <vector>

#include "euroc_files.h"
#include "fuzz_support.h"
#include "image_input.h"
#include "superdyna/io/euroc_dataset.h"

namespace superdyna::fuzz {
namespace {

namespace fs = std::filesystem;

/// A valid mono sequence with instance masks (ids 1 and 2 labelled, 3 unlabelled).
io::EurocDataset openSequence() {
  const fs::path mav0 = scratch() / "mav0";
  writeFile(mav0 / "cam0" / "sensor.yaml", kCameraSensorYaml);
  writeFile(mav0 / "cam0" / "data.csv", kCameraCsv);
  for (const char* image : {"1.png", "2.png"})
    writeFile(mav0 / "cam0" / "data" / image, "");
  fs::create_directories(mav0 / "cam0" / "mask");
  writeFile(mav0 / "instances.csv", kInstancesCsv);
  return io::EurocDataset::open(mav0);
}

std::string encodedPng(const cv::Mat& image) {
  std::vector<std::uint8_t> png;
  cv::imencode(".png", image, png);
  return std::string(png.begin(), png.end());
}

}  // namespace
}  // namespace superdyna::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace superdyna::fuzz;
  static const superdyna::io::EurocDataset dataset = openSequence();
  const std::filesystem::path image = dataset.monoFrames().front().path;
  const std::filesystem::path mask = image.parent_path().parent_path() / "mask" / "1.png";
  const SelectedInput input = selectInput(data, size);
  cv::Size expected(8, 6);
  if (input.selector & 1) {
    const cv::Mat ids = idImageFrom(input.rest);
    writeFile(mask, encodedPng(ids));
    if (!(input.selector & 2)) expected = ids.size();
  } else {
    writeFile(mask, input.rest);
  }
  expectOnlyInputErrors([&] { (void)dataset.loadInstanceMask(image, expected); });
  return 0;
}
