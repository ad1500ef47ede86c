#pragma once
// Choice of the front end's feature extractor: ORB (binary descriptors, scale pyramid) or a
// learned one (XFeat, SuperPoint, ALIKE: float descriptors, one full-resolution level), built from
// one set of options.

#include <memory>
#include <string>

#include "superdyna/features/feature_set.h"
#include "superdyna/features/orb_extractor.h"

namespace superdyna::features {

enum class FeatureType { kOrb, kXFeat, kSuperPoint, kAlike };

/// "orb" | "xfeat" | "superpoint" | "alike"; anything else is an OptionError naming `option`.
FeatureType parseFeatureType(const std::string& name, const std::string& option = "features.type");
std::string toString(FeatureType type);

struct FeatureOptions {
  FeatureType type = FeatureType::kOrb;
  /// Network file of a learned extractor: a bare name is looked up by inference::findModel()
  /// ($SUPERDYNA_MODEL_DIR, then the repository's models/), a path is used as given. Empty:
  /// the type's default name (xfeat.onnx, superpoint.onnx, alike-t.onnx). Unused by ORB.
  std::string model;
  OrbOptions orb;  ///< ORB: budget (orb.features), pyramid, FAST thresholds.
  /// Learned extractors: keypoint budget (top-K), >= 1.
  int max_keypoints = 1200;
  /// Learned extractors: heat a keypoint needs, in [0, 1); negative = the extractor's default
  /// (XFeat 0.05, SuperPoint 0.015, ALIKE 0.2).
  double detection_threshold = -1.0;
  /// Learned extractors: non-maximum suppression radius [px] (XFeat: window 2r+1, SuperPoint:
  /// radius r, ALIKE: window 2r+1 and its soft-argmax window); negative = the extractor's default
  /// (XFeat 2, SuperPoint 4, ALIKE 2). XFeat's and SuperPoint's descriptors
  /// are sampled from a 1/8-resolution map, so keypoints closer than a cell (8 px) have nearly the
  /// same descriptor: a larger radius keeps them apart for matching by projection.
  int nms_radius_px = -1;
  /// Learned extractors: spread the top-K over square cells of this side [px]; 0 = off.
  int grid_cell_px = 0;
  /// Learned extractors: the image is scaled by this factor, in (0, 1], before the network sees
  /// it (area averaging); keypoints come back in full-resolution pixels. The network's cost
  /// falls with the pixel count (ALIKE-t in the concurrent stereo pipeline on 752x480 images:
  /// 129 ms per image at 1, 52 ms at 0.6); keypoint positions are that much coarser. Radii and
  /// cell sides of the decoding (nms_radius_px, grid_cell_px) are in the scaled image's pixels.
  double input_scale = 1.0;
  /// XFeat: move each keypoint to the heat-weighted centroid of the (2r+1)^2 heatmap window
  /// around its integer maximum (keypoint_decoding.h: refineSubpixel); 0 = integer pixels.
  int subpixel_radius_px = 0;
  /// Learned extractors: ONNX Runtime intra-op threads per network, >= 1. One: the stereo front
  /// end runs the left and right networks side by side (FrontEndOptions::parallel_extraction),
  /// which uses two cores better than splitting every operator of one network over two threads.
  int inference_threads = 1;
  /// Match keypoints only within one semantic class (Keypoint::class_id), in every matcher of the
  /// system (stereo, map-to-frame, reference keyframe, monocular initialisation, triangulation).
  bool class_wise_matching = true;

  /// The model name makeExtractor() loads for a learned type ("" for ORB).
  std::string modelName() const;
  /// Throws OptionError naming the first invalid field (features.*, orb.*).
  void validate() const;
  bool operator==(const FeatureOptions&) const = default;
};

/// The scale pyramid an extractor's keypoints come from: ORB's levels; learned extractors detect
/// on one full-resolution level (scale factor 1).
struct PyramidLayout {
  double scale_factor = 1.0;
  int levels = 1;
};
PyramidLayout pyramidOf(const FeatureOptions& options);

/// The extractor the options describe. A learned model that cannot be found throws InputError
/// listing the folders searched and how to get the model.
std::unique_ptr<FeatureExtractor> makeExtractor(const FeatureOptions& options);

}  // namespace superdyna::features
