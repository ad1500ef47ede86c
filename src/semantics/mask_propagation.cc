#include "superdyna/semantics/mask_propagation.h"

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <map>
#include <vector>

#include "superdyna/core/error.h"
#include "superdyna/features/matcher.h"

namespace superdyna::semantics {

namespace {

double medianOf(std::vector<double> values) {
  const auto middle = values.begin() + static_cast<std::ptrdiff_t>(values.size() / 2);
  std::nth_element(values.begin(), middle, values.end());
  return *middle;
}

/// Component-wise median of image motions (not empty).
Eigen::Vector2d medianMotion(const std::vector<Eigen::Vector2d>& motions) {
  std::vector<double> dx, dy;
  for (const Eigen::Vector2d& m : motions) {
    dx.push_back(m.x());
    dy.push_back(m.y());
  }
  return {medianOf(std::move(dx)), medianOf(std::move(dy))};
}

Eigen::Vector2i rounded(const Eigen::Vector2d& v) {
  return {static_cast<int>(std::lround(v.x())), static_cast<int>(std::lround(v.y()))};
}

}  // namespace

void PropagationOptions::validate() const {
  if (!(radius_px > 0.0)) throw OptionError("semantics.propagation_radius_px", "must be > 0");
  if (max_hamming < 0) throw OptionError("semantics.propagation_max_hamming", "must be >= 0");
  if (!(max_l2 >= 0.0)) throw OptionError("semantics.propagation_max_l2", "must be >= 0");
  if (!(ratio > 0.0 && ratio <= 1.0)) {
    throw OptionError("semantics.propagation_ratio", "must be in (0, 1]");
  }
  if (min_matches < 1) throw OptionError("semantics.propagation_min_matches", "must be >= 1");
  if (min_instance_matches < 1) {
    throw OptionError("semantics.propagation_min_instance_matches", "must be >= 1");
  }
}

MaskPropagator::MaskPropagator(const PropagationOptions& options) : options_(options) {
  options_.validate();
}

void MaskPropagator::setReference(const sensors::InstanceMasks& masks,
                                  const features::FeatureSet& left) {
  sensors::InstanceMasks reference;
  reference.cam0 = masks.cam0;
  reference.class_of_instance = masks.class_of_instance;
  reference_masks_ = std::move(reference);
  // Its own copy of the descriptors: the frame's share a buffer with the tracker's thread, whose
  // release the propagator would otherwise race with in ThreadSanitizer's view (OpenCV's
  // reference count is atomic, but in an uninstrumented library).
  reference_features_ = left;
  reference_features_.descriptors = left.descriptors.clone();
}

sensors::InstanceMasks MaskPropagator::propagate(const features::FeatureSet& left,
                                                 PropagationStats* stats) {
  const sensors::InstanceMasks& reference = *reference_masks_;
  // Query: the reference keypoints, searched where the last image motion puts them.
  const features::KeypointGrid grid(left.keypoints, reference.cam0.size());
  const auto matchWithin = [&](double radius) {
    std::vector<Eigen::Vector2d> predicted;
    predicted.reserve(reference_features_.size());
    for (const features::Keypoint& k : reference_features_.keypoints)
      predicted.push_back(k.pixel + last_motion_);
    features::ProjectionMatchOptions match;
    match.radius_px = radius;
    match.max_distance = options_.max_hamming;
    match.max_l2_distance = options_.max_l2;
    match.ratio = options_.ratio;
    return features::matchByProjection(reference_features_, predicted, left, grid, match);
  };
  std::vector<features::Match> matches = matchWithin(options_.radius_px);
  if (static_cast<int>(matches.size()) < options_.min_matches)
    matches = matchWithin(2.0 * options_.radius_px);

  std::vector<Eigen::Vector2d> all;
  std::map<int, std::vector<Eigen::Vector2d>> of_instance;
  for (const features::Match& m : matches) {
    const Eigen::Vector2d& from = reference_features_.keypoints[m.query].pixel;
    const Eigen::Vector2d motion = left.keypoints[m.train].pixel - from;
    all.push_back(motion);
    const int id = sensors::idAtPixel(reference.cam0, from);
    if (id != 0) of_instance[id].push_back(motion);
  }
  const Eigen::Vector2d common = all.empty() ? last_motion_ : medianMotion(all);

  PropagationStats found;
  found.matches = static_cast<int>(matches.size());
  found.median_motion = common;
  std::map<int, Eigen::Vector2i> shifts;
  for (const auto& [id, cls] : reference.class_of_instance) {
    (void)cls;
    const auto own = of_instance.find(id);
    if (own != of_instance.end() &&
        static_cast<int>(own->second.size()) >= options_.min_instance_matches) {
      shifts[id] = rounded(medianMotion(own->second));
      ++found.instances_own_motion;
    } else {
      shifts[id] = rounded(common);
      ++found.instances_common_motion;
    }
  }
  last_motion_ = common;
  if (stats) *stats = found;

  sensors::InstanceMasks propagated;
  propagated.cam0 = shiftInstances(reference.cam0, shifts);
  propagated.class_of_instance = reference.class_of_instance;
  return propagated;
}

cv::Mat shiftInstances(const cv::Mat& ids, const std::map<int, Eigen::Vector2i>& shifts) {
  cv::Mat out = cv::Mat::zeros(ids.size(), CV_16UC1);
  for (int row = 0; row < ids.rows; ++row) {
    const auto* in = ids.ptr<std::uint16_t>(row);
    for (int col = 0; col < ids.cols; ++col) {
      const int id = in[col];
      if (id == 0) continue;
      const auto shift = shifts.find(id);
      const Eigen::Vector2i s = shift == shifts.end() ? Eigen::Vector2i::Zero() : shift->second;
      const int r = row + s.y();
      const int c = col + s.x();
      if (r < 0 || r >= ids.rows || c < 0 || c >= ids.cols) continue;
      std::uint16_t& target = out.at<std::uint16_t>(r, c);
      target = std::max<std::uint16_t>(target, static_cast<std::uint16_t>(id));
    }
  }
  return out;
}

}  // namespace superdyna::semantics
