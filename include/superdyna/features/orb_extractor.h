#pragma once
// ORB features in the manner of ORB-SLAM: a scale pyramid; per level a share of the keypoint
// budget proportional to the level's area; FAST corners detected cell by cell (retrying a lower
// threshold in cells without corners) and spread evenly by a quadtree; intensity-centroid
// orientation; steered-BRIEF descriptors on the Gaussian-smoothed level. Output coordinates are
// in the level-0 image.
//
// Pyramid: level l is level l - 1 resized (cv::INTER_AREA, computed by AreaShrinker) to
// round(size0 / scale_factor^l). A level pixel (x, y) maps to the level-0 pixel
// ((x + 0.5) * sx - 0.5, (y + 0.5) * sy - 0.5) with sx = width0 / width_l,
// sy = height0 / height_l (pixel centres, as cv::resize samples).

#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/features/area_resize.h"
#include "superdyna/features/feature_set.h"

namespace superdyna::features {

struct OrbOptions {
  int features = 1200;         ///< Keypoint budget over all levels, in [1, 100000].
  double scale_factor = 1.2;   ///< Scale between consecutive pyramid levels, in (1, 2].
  int levels = 8;              ///< Pyramid levels, in [1, 20].
  int fast_threshold = 20;     ///< FAST intensity threshold tried first [gray levels], [1, 254].
  int min_fast_threshold = 7;  ///< Retried in cells without corners, in [1, fast_threshold].
  int cell_size = 30;          ///< Side of the FAST detection cells [px of the level], >= 8.
  /// Keypoints keep this distance from each level's border [px of the level]; >= 16 so the
  /// orientation disc and the descriptor pattern (radius 15) stay inside the image.
  int edge_threshold = 19;
  /// Sigma of the Gaussian smoothing (7x7 kernel) before the BRIEF tests [px of the level], > 0.
  double blur_sigma = 2.0;

  /// Throws OptionError naming the first invalid field.
  void validate() const;
  bool operator==(const OrbOptions&) const = default;
};

/// ORB extractor; see the file comment. Deterministic and single-threaded.
class OrbExtractor final : public FeatureExtractor {
 public:
  /// Throws OptionError for invalid options.
  explicit OrbExtractor(const OrbOptions& options = {});

  /// Keypoints sorted by level, then as the quadtree returns them (row-major order of the
  /// detection); descriptors CV_8UC1, 32 bytes per row; DescriptorType::kBinary. Fewer keypoints
  /// than the budget when the image has too few corners. Throws InputError when `gray` is not
  /// a non-empty CV_8UC1 image.
  FeatureSet extract(const cv::Mat& gray) override;
  std::string name() const override { return "orb"; }

  const OrbOptions& options() const { return options_; }
  /// Nominal scale of each level with respect to level 0: scale_factor^level.
  const std::vector<double>& levelScales() const { return scales_; }
  /// Keypoint budget of each level (sums to options().features): proportional to the level's
  /// area, i.e. a geometric series of ratio 1 / scale_factor^2; the last level takes the rest.
  const std::vector<int>& levelTargets() const { return targets_; }
  /// The pyramid of the last extract() call (level 0 shares the input's data).
  const std::vector<cv::Mat>& pyramid() const { return pyramid_; }

 private:
  void buildPyramid(const cv::Mat& gray);
  /// FAST corners of one level inside the detection border, cell by cell [px of the level].
  std::vector<cv::KeyPoint> detectCorners(const cv::Mat& level) const;
  /// Orients, describes and appends the chosen corners of one level.
  void describeLevel(int level, const std::vector<cv::KeyPoint>& corners,
                     const std::vector<int>& chosen, FeatureSet& features) const;

  OrbOptions options_;
  std::vector<double> scales_;
  std::vector<int> targets_;
  std::vector<cv::Mat> pyramid_;
  std::vector<AreaShrinker> shrinkers_;  ///< Level l - 1 to l, for the last input size.
};

}  // namespace superdyna::features
