#include "superdyna/tracking/front_end.h"

#include <algorithm>
#include <chrono>
#include <cmath>
#include <cstdint>
#include <limits>

#include "superdyna/core/time.h"

namespace superdyna::tracking {

static_assert(sensors::kInstanceClassBackground == features::kClassBackground &&
                  sensors::kInstanceClassVehicle == features::kClassVehicle &&
                  sensors::kInstanceClassPedestrian == features::kClassPedestrian &&
                  sensors::kInstanceClassOtherMovable == features::kClassOtherMovable,
              "instance-mask classes and keypoint classes must use the same ids");

namespace {

using Clock = std::chrono::steady_clock;

Eigen::Vector2d notANumber() {
  return Eigen::Vector2d::Constant(std::numeric_limits<double>::quiet_NaN());
}

Eigen::Vector2d normalizedOf(const CameraModel& camera, const Eigen::Vector2d& pixel) {
  const auto bearing = camera.unproject(pixel);
  if (!bearing || !((*bearing).z() > 1e-6)) return notANumber();
  return Eigen::Vector2d(bearing->x() / bearing->z(), bearing->y() / bearing->z());
}

}  // namespace

int Frame::numStereo() const {
  return static_cast<int>(
      std::count_if(depth_m.begin(), depth_m.end(), [](double d) { return d > 0.0; }));
}

Frame Frame::withoutKeypoints(const std::vector<char>& drop, std::vector<int>* kept) const {
  std::vector<int> indices;
  for (std::size_t i = 0; i < size(); ++i) {
    if (!drop[i]) indices.push_back(static_cast<int>(i));
  }
  Frame out;
  out.index = index;
  out.t_ns = t_ns;
  out.features = features.select(indices);
  for (const int i : indices) {
    out.normalized.push_back(normalized[i]);
    out.depth_m.push_back(depth_m[i]);
    out.p_c0.push_back(p_c0[i]);
    out.right_normalized.push_back(right_normalized[i]);
  }
  out.imu = imu;
  out.extract_ms = extract_ms;
  out.stereo_ms = stereo_ms;
  out.cross_class_stereo = cross_class_stereo;
  if (kept) kept->insert(kept->end(), indices.begin(), indices.end());
  return out;
}

void FrontEndOptions::validate() const {
  features.validate();
  stereo.validate();
}

double instanceBorderRadiusPx(const features::Keypoint& keypoint) {
  return std::max(3.0, 0.1 * keypoint.size);
}

namespace {

/// Whether another id than `id` lies on the square of half-side `radius` around `pixel` (its
/// corners and edge midpoints, within the image).
bool otherIdAround(const cv::Mat& ids, const Eigen::Vector2d& pixel, double radius, int id) {
  for (const int dy : {-1, 0, 1}) {
    for (const int dx : {-1, 0, 1}) {
      if (dx == 0 && dy == 0) continue;
      const Eigen::Vector2d p = pixel + radius * Eigen::Vector2d(dx, dy);
      if (p.x() < 0.0 || p.y() < 0.0 || p.x() > ids.cols - 1 || p.y() > ids.rows - 1) continue;
      if (sensors::idAtPixel(ids, p) != id) return true;
    }
  }
  return false;
}

}  // namespace

void labelKeypoints(const cv::Mat& instance_mask, const sensors::InstanceMasks& masks,
                    std::vector<features::Keypoint>& keypoints) {
  if (instance_mask.empty()) return;
  for (features::Keypoint& k : keypoints) {
    k.instance_id = sensors::idAtPixel(instance_mask, k.pixel);
    k.class_id = masks.classOf(k.instance_id);
    k.on_instance_border =
        otherIdAround(instance_mask, k.pixel, instanceBorderRadiusPx(k), k.instance_id);
  }
}

FrontEnd::FrontEnd(const FrontEndOptions& options, const sensors::CameraCalibration& cam0,
                   const std::optional<sensors::CameraCalibration>& cam1)
    : camera0_(cam0.cameraModel()), pyramid_(features::pyramidOf(options.features)) {
  options.validate();
  left_extractor_ = features::makeExtractor(options.features);
  if (cam1) {
    right_extractor_ = features::makeExtractor(options.features);
    stereo_matcher_.emplace(cam0, *cam1, options.stereo);
    features::StereoMatchOptions label_free = options.stereo;
    label_free.same_class_only = false;
    label_free_matcher_.emplace(cam0, *cam1, label_free);
    if (options.parallel_extraction) helper_ = std::make_unique<TaskThread>();
  }
}

Frame FrontEnd::build(const sensors::FrameBundle& bundle) {
  return build(bundle, {});
}

Frame FrontEnd::build(const sensors::FrameBundle& bundle, const MasksOfFeatures& masks_of) {
  Frame frame;
  frame.index = bundle.index;
  frame.t_ns = bundle.t_ns;
  frame.imu = bundle.imu;
  const bool stereo = stereo_matcher_ && !bundle.image1.empty();
  auto start = Clock::now();
  features::FeatureSet right;
  extract(bundle, stereo, frame, right);
  frame.extract_ms = millisecondsSince(start);
  // Waiting for the masks is the segmentation's time, not the front end's.
  std::optional<sensors::InstanceMasks> masks = bundle.masks;
  if (!masks && masks_of) masks = masks_of(frame.features);

  start = Clock::now();
  if (masks) {
    labelKeypoints(masks->cam0, *masks, frame.features.keypoints);
    labelKeypoints(masks->cam1, *masks, right.keypoints);
  }
  const std::size_t n = frame.features.size();
  frame.normalized.resize(n);
  frame.depth_m.assign(n, -1.0);
  frame.p_c0.assign(n, Eigen::Vector3d::Zero());
  frame.right_normalized.assign(n, std::nullopt);
  for (std::size_t i = 0; i < n; ++i)
    frame.normalized[i] = normalizedOf(camera0_, frame.features.keypoints[i].pixel);
  if (stereo) matchStereo(right, bundle, masks, frame);
  frame.stereo_ms = millisecondsSince(start);
  return frame;
}

void FrontEnd::extract(const sensors::FrameBundle& bundle, bool stereo, Frame& frame,
                       features::FeatureSet& right) {
  if (!stereo) {
    frame.features = left_extractor_->extract(bundle.image0);
    return;
  }
  if (!helper_) {
    frame.features = left_extractor_->extract(bundle.image0);
    right = right_extractor_->extract(bundle.image1);
    return;
  }
  helper_->run([&] { right = right_extractor_->extract(bundle.image1); });
  try {
    frame.features = left_extractor_->extract(bundle.image0);
  } catch (...) {
    // The job refers to `bundle` and `right`: let it finish before they go.
    try {
      helper_->wait();
    } catch (...) {
    }
    throw;
  }
  helper_->wait();
}

void FrontEnd::matchStereo(const features::FeatureSet& right, const sensors::FrameBundle& bundle,
                           const std::optional<sensors::InstanceMasks>& masks, Frame& frame) const {
  // Right keypoints are labelled only when the right image has a mask of its own.
  const bool right_labelled = !masks || !masks->cam1.empty();
  const features::StereoMatcher& matcher = right_labelled ? *stereo_matcher_ : *label_free_matcher_;
  const std::vector<features::StereoMatch> matches =
      matcher.options().refine_on_images ? matcher.match(frame.features, right, bundle.image0,
                                                         bundle.image1, pyramid_.scale_factor)
                                         : matcher.match(frame.features, right);
  for (const features::StereoMatch& m : matches) {
    const auto i = static_cast<std::size_t>(m.left);
    if (!frame.normalized[i].allFinite()) continue;
    const features::Keypoint& partner = right.keypoints[static_cast<std::size_t>(m.right)];
    const Eigen::Vector2d r = normalizedOf(stereo_matcher_->camera1(), m.right_pixel);
    if (!r.allFinite()) continue;
    if (right_labelled && partner.class_id != frame.features.keypoints[i].class_id) {
      ++frame.cross_class_stereo;
    }
    frame.depth_m[i] = m.depth_m;
    frame.p_c0[i] = m.p_c0;
    frame.right_normalized[i] = r;
  }
}

}  // namespace superdyna::tracking
