// Instance segmentation over a folder of images (not a test): per frame the instances a YOLO
// model (or SAM prompted by YOLOX boxes) finds by class, with their mask areas, and the time per
// image; optionally overlay PNGs.
//
//   superdyna_segment_bench --images ../shared/data/kitti/snippet_1/image_l
//       [--segmenter yolo|sam] [--model ../shared/models/yolov8n-seg-int8.onnx] [--frames N]
//       [--threads 2] [--resize 752x480] [--overlay DIR] [--quiet]
//
// Times are wall-clock per call of Segmenter::segment (pre-processing, ONNX Runtime, decoding;
// yolo after one warm-up run); on a shared machine they include whatever else runs on the cores.
// sam: the detector and decoder models are looked up as the run command does
// ($SUPERDYNA_MODEL_DIR, then models/; yolox_nano.onnx defaults to ../shared/models).

#include <fmt/format.h>

#include <CLI/CLI.hpp>
#include <algorithm>
#include <chrono>
#include <filesystem>
#include <memory>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <string>
#include <vector>

#include "superdyna/semantics/overlay.h"
#include "superdyna/semantics/sam_segmenter.h"
#include "superdyna/semantics/yolo_segmenter.h"

namespace fs = std::filesystem;
using namespace superdyna;

namespace {

std::vector<fs::path> imagesIn(const fs::path& dir) {
  std::vector<fs::path> files;
  for (const auto& entry : fs::directory_iterator(dir))
    if (entry.path().extension() == ".png" || entry.path().extension() == ".jpg")
      files.push_back(entry.path());
  std::sort(files.begin(), files.end());
  return files;
}

std::string areasOf(const semantics::Segmentation& segmentation, int class_id) {
  std::string text;
  for (const semantics::Instance& instance : segmentation.instances)
    if (instance.class_id == class_id)
      text +=
          fmt::format("{}{} {:.2f}", text.empty() ? "" : ", ", instance.area_px, instance.score);
  return text;
}

}  // namespace

int main(int argc, char** argv) {
  CLI::App app("Instance segmentation benchmark");
  semantics::YoloOptions options;
  options.model = std::string(SUPERDYNA_SHARED_DIR) + "/models/yolov8n-seg-int8.onnx";
  semantics::SamOptions sam_options;
  sam_options.detector_model = std::string(SUPERDYNA_SHARED_DIR) + "/models/yolox_nano.onnx";
  std::string backend = "yolo";
  fs::path images, overlay;
  int frames = 0;
  std::string resize;
  bool quiet = false;
  app.add_option("--segmenter", backend, "yolo or sam")
      ->check(CLI::IsMember({"yolo", "sam"}))
      ->capture_default_str();
  app.add_option("--model", options.model, "YOLOv8-seg ONNX file")->capture_default_str();
  app.add_option("--detector", sam_options.detector_model, "sam: the YOLOX ONNX file")
      ->capture_default_str();
  app.add_option("--images", images, "Folder of images")->required()->check(CLI::ExistingDirectory);
  app.add_option("--frames", frames, "At most this many images (0 = all)");
  app.add_option("--threads", options.inference_threads, "ONNX Runtime threads")
      ->capture_default_str();
  app.add_option("--input-size", options.input_size, "Input side for dynamic models");
  app.add_option("--resize", resize, "Resize every image to WxH first (e.g. 752x480)");
  app.add_option("--overlay", overlay, "Write overlay PNGs here");
  app.add_flag("--quiet", quiet, "Only the summary");
  CLI11_PARSE(app, argc, argv);

  try {
    sam_options.inference_threads = options.inference_threads;
    std::unique_ptr<semantics::YoloSegmenter> yolo;
    std::unique_ptr<semantics::SamSegmenter> sam;
    if (backend == "sam") {
      sam = std::make_unique<semantics::SamSegmenter>(sam_options, semantics::Taxonomy{});
    } else {
      yolo = std::make_unique<semantics::YoloSegmenter>(options, semantics::Taxonomy{});
    }
    semantics::Segmenter& segmenter =
        sam ? static_cast<semantics::Segmenter&>(*sam) : static_cast<semantics::Segmenter&>(*yolo);
    cv::Size target;
    if (!resize.empty() &&
        std::sscanf(resize.c_str(), "%dx%d", &target.width, &target.height) != 2) {
      throw std::runtime_error("--resize expects WxH");
    }
    if (!overlay.empty()) fs::create_directories(overlay);
    std::vector<fs::path> files = imagesIn(images);
    if (frames > 0 && static_cast<int>(files.size()) > frames) files.resize(frames);
    fmt::print("{}; {} images of {}; {} ONNX Runtime threads\n", segmenter.description(),
               files.size(), images.string(), options.inference_threads);
    double total_ms = 0.0;
    int with_vehicles = 0;
    for (const fs::path& file : files) {
      cv::Mat image = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
      if (image.empty()) throw std::runtime_error("cannot read " + file.string());
      if (!target.empty()) cv::resize(image, image, target, 0, 0, cv::INTER_AREA);
      const auto start = std::chrono::steady_clock::now();
      const semantics::Segmentation segmentation = segmenter.segment(image, 0, 0);
      const double ms =
          std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
              .count();
      total_ms += ms;
      const auto count = [&](int class_id) {
        return std::count_if(segmentation.instances.begin(), segmentation.instances.end(),
                             [&](const semantics::Instance& i) { return i.class_id == class_id; });
      };
      with_vehicles += count(sensors::kInstanceClassVehicle) > 0;
      if (!quiet) {
        fmt::print("{}: vehicles {} (area px, score: {}), pedestrians {} ({}), {:.1f} ms\n",
                   file.filename().string(), count(sensors::kInstanceClassVehicle),
                   areasOf(segmentation, sensors::kInstanceClassVehicle),
                   count(sensors::kInstanceClassPedestrian),
                   areasOf(segmentation, sensors::kInstanceClassPedestrian), ms);
      }
      if (!overlay.empty()) {
        sensors::InstanceMasks masks;
        for (const semantics::Instance& i : segmentation.instances)
          masks.class_of_instance[i.id] = i.class_id;
        cv::imwrite((overlay / file.filename()).string(),
                    semantics::drawOverlay(image, segmentation.ids, masks, {}));
      }
    }
    const double n = std::max<double>(1.0, static_cast<double>(files.size()));
    const std::string networks =
        sam ? fmt::format(
                  "YOLOX {:.1f} ms per image, SAM encoder {:.1f} ms per image with "
                  "detections, SAM decoder {:.1f} ms per detection",
                  sam->meanDetectorMs(), sam->meanEncoderMs(), sam->meanDecoderMs())
            : fmt::format("ONNX Runtime {:.1f} ms", yolo->meanInferenceMs());
    fmt::print("{} of {} images with vehicles; mean per image: segment {:.1f} ms, of which {}\n",
               with_vehicles, files.size(), total_ms / n, networks);
  } catch (const std::exception& e) {
    fmt::print(stderr, "error: {}\n", e.what());
    return 2;
  }
  return 0;
}
