#include "superdyna/tracking/front_end.h"

#include <algorithm>
#include <chrono>
#include <limits>

namespace superdyna::tracking {

namespace {

using Clock = std::chrono::steady_clock;

double millisecondsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

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

void FrontEndOptions::validate() const {
  orb.validate();
  stereo.validate();
}

FrontEnd::FrontEnd(const FrontEndOptions& options, const io::CameraCalibration& cam0,
                   const std::optional<io::CameraCalibration>& cam1)
    : camera0_(cam0.cameraModel()), left_extractor_(options.orb), right_extractor_(options.orb) {
  options.validate();
  if (cam1) stereo_matcher_.emplace(cam0, *cam1, options.stereo);
}

Frame FrontEnd::build(const io::FrameBundle& bundle) {
  Frame frame;
  frame.index = bundle.index;
  frame.t_ns = bundle.t_ns;
  frame.imu = bundle.imu;
  const bool stereo = stereo_matcher_ && !bundle.image1.empty();
  auto start = Clock::now();
  frame.features = left_extractor_.extract(bundle.image0);
  features::FeatureSet right;
  if (stereo) right = right_extractor_.extract(bundle.image1);
  frame.extract_ms = millisecondsSince(start);

  start = Clock::now();
  const std::size_t n = frame.features.size();
  frame.normalized.resize(n);
  frame.depth_m.assign(n, -1.0);
  frame.p_c0.assign(n, Eigen::Vector3d::Zero());
  frame.right_normalized.assign(n, std::nullopt);
  for (std::size_t i = 0; i < n; ++i)
    frame.normalized[i] = normalizedOf(camera0_, frame.features.keypoints[i].pixel);
  if (stereo) matchStereo(right, frame);
  frame.stereo_ms = millisecondsSince(start);
  return frame;
}

void FrontEnd::matchStereo(const features::FeatureSet& right, Frame& frame) const {
  for (const features::StereoMatch& m : stereo_matcher_->match(frame.features, right)) {
    const auto i = static_cast<std::size_t>(m.left);
    if (!frame.normalized[i].allFinite()) continue;
    const Eigen::Vector2d r = normalizedOf(
        stereo_matcher_->camera1(), right.keypoints[static_cast<std::size_t>(m.right)].pixel);
    if (!r.allFinite()) continue;
    frame.depth_m[i] = m.depth_m;
    frame.p_c0[i] = m.p_c0;
    frame.right_normalized[i] = r;
  }
}

}  // namespace superdyna::tracking
