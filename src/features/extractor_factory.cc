#include "superdyna/features/extractor_factory.h"

#include <fmt/format.h>

#include "superdyna/core/error.h"
#include "superdyna/features/alike_extractor.h"
#include "superdyna/features/keypoint_decoding.h"
#include "superdyna/features/superpoint_extractor.h"
#include "superdyna/features/xfeat_extractor.h"

namespace superdyna::features {

namespace {

XFeatOptions xfeatOptions(const FeatureOptions& options) {
  XFeatOptions xfeat;
  xfeat.model = options.modelName();
  xfeat.max_keypoints = options.max_keypoints;
  if (options.detection_threshold >= 0.0) {
    xfeat.detection_threshold = static_cast<float>(options.detection_threshold);
  }
  if (options.nms_radius_px >= 0) xfeat.nms_window = 2 * options.nms_radius_px + 1;
  xfeat.grid_cell_px = options.grid_cell_px;
  xfeat.input_scale = options.input_scale;
  xfeat.subpixel_radius = options.subpixel_radius_px;
  xfeat.runtime.intra_op_threads = options.inference_threads;
  return xfeat;
}

SuperPointOptions superPointOptions(const FeatureOptions& options) {
  SuperPointOptions superpoint;
  superpoint.model = options.modelName();
  superpoint.max_keypoints = options.max_keypoints;
  if (options.detection_threshold >= 0.0) {
    superpoint.confidence_threshold = static_cast<float>(options.detection_threshold);
  }
  if (options.nms_radius_px >= 0) superpoint.nms_radius = options.nms_radius_px;
  superpoint.grid_cell_px = options.grid_cell_px;
  superpoint.input_scale = options.input_scale;
  superpoint.runtime.intra_op_threads = options.inference_threads;
  return superpoint;
}

AlikeOptions alikeOptions(const FeatureOptions& options) {
  AlikeOptions alike;
  alike.model = options.modelName();
  alike.max_keypoints = options.max_keypoints;
  if (options.detection_threshold >= 0.0) {
    alike.score_threshold = static_cast<float>(options.detection_threshold);
  }
  if (options.nms_radius_px >= 1) alike.radius = options.nms_radius_px;
  alike.grid_cell_px = options.grid_cell_px;
  alike.input_scale = options.input_scale;
  alike.runtime.intra_op_threads = options.inference_threads;
  return alike;
}

}  // namespace

FeatureType parseFeatureType(const std::string& name, const std::string& option) {
  if (name == "orb") return FeatureType::kOrb;
  if (name == "xfeat") return FeatureType::kXFeat;
  if (name == "superpoint") return FeatureType::kSuperPoint;
  if (name == "alike") return FeatureType::kAlike;
  throw OptionError(
      option, fmt::format("unknown feature type '{}' (orb | xfeat | superpoint | alike)", name));
}

std::string toString(FeatureType type) {
  switch (type) {
    case FeatureType::kOrb:
      return "orb";
    case FeatureType::kXFeat:
      return "xfeat";
    case FeatureType::kSuperPoint:
      return "superpoint";
    case FeatureType::kAlike:
      return "alike";
  }
  return "unknown";
}

std::string FeatureOptions::modelName() const {
  if (type == FeatureType::kOrb) return "";
  if (!model.empty()) return model;
  switch (type) {
    case FeatureType::kXFeat:
      return "xfeat.onnx";
    case FeatureType::kAlike:
      return "alike-t.onnx";
    default:
      return "superpoint.onnx";
  }
}

void FeatureOptions::validate() const {
  if (type == FeatureType::kOrb) {
    orb.validate();
  }
  if (max_keypoints < 1) {
    throw OptionError("features.max_keypoints", fmt::format("must be >= 1, got {}", max_keypoints));
  }
  if (!(detection_threshold < 1.0)) {
    throw OptionError("features.detection_threshold",
                      fmt::format("must be < 1 (negative: the extractor's default), got {}",
                                  detection_threshold));
  }
  if (grid_cell_px < 0) {
    throw OptionError("features.grid_cell_px", fmt::format("must be >= 0, got {}", grid_cell_px));
  }
  checkInputScale(input_scale, "features.input_scale");
  if (subpixel_radius_px < 0) {
    throw OptionError("features.subpixel_radius_px",
                      fmt::format("must be >= 0, got {}", subpixel_radius_px));
  }
  if (inference_threads < 1) {
    throw OptionError("features.inference_threads",
                      fmt::format("must be >= 1, got {}", inference_threads));
  }
}

PyramidLayout pyramidOf(const FeatureOptions& options) {
  if (options.type == FeatureType::kOrb) return {options.orb.scale_factor, options.orb.levels};
  return {1.0, 1};
}

std::unique_ptr<FeatureExtractor> makeExtractor(const FeatureOptions& options) {
  options.validate();
  switch (options.type) {
    case FeatureType::kOrb:
      return std::make_unique<OrbExtractor>(options.orb);
    case FeatureType::kXFeat:
      return std::make_unique<XFeatExtractor>(xfeatOptions(options));
    case FeatureType::kSuperPoint:
      return std::make_unique<SuperPointExtractor>(superPointOptions(options));
    case FeatureType::kAlike:
      return std::make_unique<AlikeExtractor>(alikeOptions(options));
  }
  throw OptionError("features.type", "unknown feature type");
}

}  // namespace superdyna::features
