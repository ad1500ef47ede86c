#include "superdyna/tracking/reference_matching.h"

#include <algorithm>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "superdyna/core/error.h"

namespace superdyna::tracking {

namespace {

/// PnP needs a few more correspondences than its minimal sample.
constexpr int kMinPnpCorrespondences = 6;

struct Correspondences {
  std::vector<cv::Point3d> p_w;
  std::vector<cv::Point2d> normalized;
};

Correspondences usableCorrespondences(const Frame& frame, const ReferenceView& view,
                                      const std::vector<features::Match>& matches) {
  Correspondences out;
  for (const features::Match& m : matches) {
    const Eigen::Vector2d& n = frame.normalized[static_cast<std::size_t>(m.train)];
    if (!n.allFinite()) continue;  // undistortion failed
    const Eigen::Vector3d& p = view.p_w[static_cast<std::size_t>(m.query)];
    out.p_w.emplace_back(p.x(), p.y(), p.z());
    out.normalized.emplace_back(n.x(), n.y());
  }
  return out;
}

/// Body pose from OpenCV's world-to-camera rotation vector and translation.
SE3d bodyPoseFromPnp(const cv::Mat& rvec, const cv::Mat& tvec, const SE3d& T_b_c0) {
  cv::Mat R_cv;
  cv::Rodrigues(rvec, R_cv);
  Eigen::Matrix3d R_c_w;
  Eigen::Vector3d t_c_w;
  cv::cv2eigen(R_cv, R_c_w);
  cv::cv2eigen(tvec, t_c_w);
  const SE3d T_c_w(R_c_w, t_c_w);
  return T_c_w.inverse() * T_b_c0.inverse();
}

}  // namespace

void ReferenceMatchingOptions::validate() const {
  matching.validate();
  if (!(ransac_threshold_px > 0.0)) {
    throw OptionError("tracker.reference_ransac_threshold_px", "must be > 0");
  }
  if (ransac_iterations <= 0) {
    throw OptionError("tracker.reference_ransac_iterations", "must be > 0");
  }
  if (min_inliers < 3) throw OptionError("tracker.reference_min_inliers", "must be >= 3");
  if (!(search_radius_px > 0.0)) {
    throw OptionError("tracker.reference_search_radius_px", "must be > 0");
  }
  if (!(ransac_confidence > 0.0 && ransac_confidence < 1.0)) {
    throw OptionError("tracker.reference_ransac_confidence", "must be in (0, 1)");
  }
}

std::optional<ReferencePose> poseFromReference(const Frame& frame, const ReferenceView& view,
                                               const SE3d& T_b_c0, double focal_px,
                                               const ReferenceMatchingOptions& options) {
  const int needed = std::max(options.min_inliers, kMinPnpCorrespondences);
  if (static_cast<int>(view.features.size()) < needed || static_cast<int>(frame.size()) < needed) {
    return std::nullopt;
  }
  const std::vector<features::Match> matches =
      features::matchBruteForce(view.features, frame.features, options.matching);
  const Correspondences c = usableCorrespondences(frame, view, matches);
  if (static_cast<int>(c.p_w.size()) < needed) return std::nullopt;

  cv::Mat rvec, tvec;
  std::vector<int> inliers;
  // Identity intrinsics: the observations are undistorted normalised coordinates. OpenCV's
  // RANSAC draws from its own fixed-seed generator, so the result is deterministic.
  const bool solved =
      cv::solvePnPRansac(c.p_w, c.normalized, cv::Mat::eye(3, 3, CV_64F), cv::noArray(), rvec, tvec,
                         false, options.ransac_iterations, options.ransac_threshold_px / focal_px,
                         options.ransac_confidence, inliers, cv::SOLVEPNP_EPNP);
  if (!solved || static_cast<int>(inliers.size()) < needed) return std::nullopt;
  ReferencePose pose;
  pose.T_w_b = bodyPoseFromPnp(rvec, tvec, T_b_c0);
  pose.matches = static_cast<int>(c.p_w.size());
  pose.inliers = static_cast<int>(inliers.size());
  return pose;
}

}  // namespace superdyna::tracking
