#include "superdyna/features/feature_set.h"

#include <fmt/format.h>

#include "superdyna/core/error.h"

namespace superdyna::features {

std::string toString(DescriptorType type) {
  switch (type) {
    case DescriptorType::kBinary:
      return "binary";
    case DescriptorType::kFloat:
      return "float";
  }
  return "unknown";
}

void FeatureSet::validate() const {
  if (descriptors.rows != static_cast<int>(keypoints.size())) {
    throw InputError(fmt::format("feature set: {} descriptor rows for {} keypoints",
                                 descriptors.rows, keypoints.size()));
  }
  if (descriptors.empty()) return;
  const int expected = descriptor_type == DescriptorType::kBinary ? CV_8UC1 : CV_32FC1;
  if (descriptors.type() != expected) {
    throw InputError(fmt::format("feature set: {} descriptors stored with OpenCV type {}",
                                 toString(descriptor_type), descriptors.type()));
  }
}

FeatureSet FeatureSet::select(const std::vector<int>& indices) const {
  FeatureSet out;
  out.descriptor_type = descriptor_type;
  out.image_size = image_size;
  out.keypoints.reserve(indices.size());
  if (!descriptors.empty()) {
    out.descriptors.create(static_cast<int>(indices.size()), descriptors.cols, descriptors.type());
  }
  for (std::size_t k = 0; k < indices.size(); ++k) {
    const int i = indices[k];
    out.keypoints.push_back(keypoints.at(static_cast<std::size_t>(i)));
    if (!descriptors.empty()) descriptors.row(i).copyTo(out.descriptors.row(static_cast<int>(k)));
  }
  return out;
}

}  // namespace superdyna::features
