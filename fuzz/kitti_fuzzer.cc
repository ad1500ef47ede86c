// libFuzzer target: the text files of a KITTI odometry sequence (calib.txt, times.txt, poses.txt),
// read by io::KittiDataset::open. The first input byte chooses the file the rest of the input
// replaces; the other files are small valid ones for the sequence's two stereo pairs.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <opencv2/core.hpp>
#include <opencv2/imgcodecs.hpp>

#include "fuzz_support.h"
#include "superdyna/io/kitti_dataset.h"

namespace superdyna::fuzz {
namespace {

namespace fs = std::filesystem;

constexpr const char* kCalib =
    "P0: 7.0e+02 0 6.0e+02 0 0 7.0e+02 1.8e+02 0 0 0 1 0\n"
    "P1: 7.0e+02 0 6.0e+02 -3.8e+02 0 7.0e+02 1.8e+02 0 0 0 1 0\n";
constexpr const char* kTimes = "0.000000e+00\n1.036224e-01\n";
constexpr const char* kPoses =
    "1 0 0 0 0 1 0 0 0 0 1 0\n"
    "0.9999 0.0141 0 0.01 -0.0141 0.9999 0 -0.02 0 0 1 0.8\n";

/// The sequence's images: two 8x6 grayscale stereo pairs.
fs::path makeSequence() {
  const fs::path dir = scratch() / "kitti";
  const cv::Mat image(6, 8, CV_8UC1, cv::Scalar(128));
  for (const char* folder : {"image_0", "image_1"}) {
    fs::create_directories(dir / folder);
    for (const char* name : {"000000.png", "000001.png"})
      cv::imwrite((dir / folder / name).string(), image);
  }
  return dir;
}

}  // namespace
}  // namespace superdyna::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace superdyna::fuzz;
  static const std::filesystem::path dir = makeSequence();
  static FileSet files(
      {{dir / "calib.txt", kCalib}, {dir / "times.txt", kTimes}, {dir / "poses.txt", kPoses}});
  const SelectedInput input = selectInput(data, size);
  files.replace(input.selector % files.size(), input.rest);
  expectOnlyInputErrors([&] {
    const superdyna::io::KittiDataset dataset = superdyna::io::KittiDataset::open(dir);
    (void)dataset.leftCalibration().cameraModel();
    (void)dataset.baseline();
  });
  return 0;
}
