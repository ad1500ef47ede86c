#pragma once
// Matching of float descriptors (XFeat, SuperPoint; rows of CV_32FC1 matrices) by Euclidean
// distance: exhaustive mutual nearest neighbours with Lowe's ratio test. XFeat's authors match
// their descriptors by mutual nearest neighbours; the ratio test is optional (ratio 1 disables it).
// For the binary (ORB) counterpart see matcher.h.

#include <opencv2/core.hpp>
#include <vector>

#include "superdyna/features/feature_set.h"

namespace superdyna::features {

/// A correspondence between query row `query` and train row `train`.
struct FloatMatch {
  int query = -1;
  int train = -1;
  float distance = 0.0f;  ///< Euclidean distance of the two descriptors.
};

/// For each query row, its nearest train row; kept when the query is also that train row's
/// nearest query row (mutual) and, with ratio < 1, best < ratio * second best distance among the
/// train rows. Ties go to the lower index; matches are ordered by query index. Throws
/// InputError unless both are CV_32FC1 with equal column counts (an empty matrix gives no
/// matches) and OptionError unless ratio is in (0, 1].
std::vector<FloatMatch> matchFloatMutualNN(const cv::Mat& query, const cv::Mat& train,
                                           double ratio = 1.0);

/// The same on two feature sets; throws InputError unless both are DescriptorType::kFloat.
std::vector<FloatMatch> matchFloatMutualNN(const FeatureSet& query, const FeatureSet& train,
                                           double ratio = 1.0);

}  // namespace superdyna::features
