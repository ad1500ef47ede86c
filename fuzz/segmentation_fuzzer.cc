// libFuzzer target: the dataset segmentation backend (semantics::DatasetSegmenter) of a EuRoC
// sequence: colour tables ("id,r,g,b"), movable-id lists ("id, name"), colour segmentation images
// and instance masks. The selector byte (mod 5) chooses what the rest of the input is:
//   0 colour table, 1 movable-id list, 2 colour segmentation image file, 3 a small colour image
//   built from the input (image_input.h: each byte picks a colour of the table, or one it does
//   not list), 4 a small 16-bit instance mask built from the input.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <opencv2/imgcodecs.hpp>
#include <vector>

#include "euroc_files.h"
#include "fuzz_support.h"
#include "image_input.h"
#include "superdyna/semantics/dataset_segmenter.h"

namespace superdyna::fuzz {
namespace {

namespace fs = std::filesystem;

constexpr const char* kColourTable = "id,r,g,b\n0,0,0,0\n1,255,0,0\n2,0,255,0\n7,0,0,255\n";
constexpr const char* kMovableIds = "id, name\n1, car\n7, truck\n";
/// The table's colours (BGR) and one it does not list.
const cv::Vec3b kPalette[] = {{0, 0, 0}, {0, 0, 255}, {0, 255, 0}, {255, 0, 0}, {9, 9, 9}};

struct Sequence {
  fs::path mav0;
  fs::path colour_table;
  fs::path movable_ids;
  fs::path segmentation;  ///< The colour segmentation image of cam0's first frame.
  fs::path mask;          ///< The instance mask of cam0's first frame.
};

Sequence makeSequence() {
  Sequence s;
  s.mav0 = scratch() / "mav0";
  writeFile(s.mav0 / "cam0" / "sensor.yaml", kCameraSensorYaml);
  writeFile(s.mav0 / "cam0" / "data.csv", kCameraCsv);
  for (const char* image : {"1.png", "2.png"})
    writeFile(s.mav0 / "cam0" / "data" / image, "");
  writeFile(s.mav0 / "instances.csv", kInstancesCsv);
  s.colour_table = scratch() / "colours.csv";
  s.movable_ids = scratch() / "movable_ids.txt";
  s.segmentation = s.mav0 / "cam0" / "segmentation" / "1.png";
  s.mask = s.mav0 / "cam0" / "mask" / "1.png";
  fs::create_directories(s.segmentation.parent_path());
  fs::create_directories(s.mask.parent_path());
  return s;
}

void writePng(const fs::path& file, const cv::Mat& image) {
  std::vector<std::uint8_t> png;
  cv::imencode(".png", image, png);
  writeFile(file, std::string_view(reinterpret_cast<const char*>(png.data()), png.size()));
}

/// Writes the fuzzed file of `mode` and the valid others; returns the size of the image to
/// segment (the calibrated 8x6, or the size of an image built from the input).
cv::Size writeFiles(const Sequence& s, int mode, std::string_view rest) {
  writeFile(s.colour_table, mode == 0 ? rest : kColourTable);
  writeFile(s.movable_ids, mode == 1 ? rest : kMovableIds);
  cv::Size size(8, 6);
  if (mode == 2) {
    writeFile(s.segmentation, rest);
  } else if (mode == 3) {
    const cv::Mat bgr = colourImageFrom(rest, kPalette);
    writePng(s.segmentation, bgr);
    size = bgr.size();
  } else {
    writePng(s.segmentation, cv::Mat(size, CV_8UC3, cv::Scalar(0, 0, 255)));
  }
  if (mode == 4) {
    const cv::Mat ids = idImageFrom(rest);
    writePng(s.mask, ids);
    size = ids.size();
  } else {
    writePng(s.mask, cv::Mat(size, CV_16UC1, cv::Scalar(1)));
  }
  return size;
}

void segmentFirstFrame(const Sequence& s, int mode, cv::Size size) {
  semantics::SegmenterOptions options;
  options.dataset_format = mode == 4 ? "masks" : "color";
  options.color_table = s.colour_table.string();
  options.movable_ids = s.movable_ids.string();
  semantics::DatasetSegmenter segmenter(s.mav0, options);
  const cv::Mat image(size, CV_8UC1, cv::Scalar(0));
  (void)segmenter.segment(image, 1'000'000'000, 0);
}

}  // namespace
}  // namespace superdyna::fuzz

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace superdyna::fuzz;
  static const Sequence sequence = makeSequence();
  const SelectedInput input = selectInput(data, size);
  const int mode = input.selector % 5;
  const cv::Size image_size = writeFiles(sequence, mode, input.rest);
  expectOnlyInputErrors([&] { segmentFirstFrame(sequence, mode, image_size); });
  return 0;
}
