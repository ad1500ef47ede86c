#include "superdyna/tracking/mono_initializer.h"

#include <Eigen/SVD>
#include <algorithm>
#include <cmath>
#include <opencv2/calib3d.hpp>
#include <opencv2/core/eigen.hpp>

#include "superdyna/core/error.h"
#include "superdyna/optim/reprojection_factor.h"
#include "superdyna/optim/triangulation.h"

namespace superdyna::tracking {

void MonoInitializerOptions::validate() const {
  if (min_features < 8) throw OptionError("mono_init.min_features", "must be >= 8");
  if (min_matches < 8) throw OptionError("mono_init.min_matches", "must be >= 8");
  if (!(search_radius_px > 0.0)) throw OptionError("mono_init.search_radius_px", "must be > 0");
  if (max_distance < 0) throw OptionError("mono_init.max_distance", "must be >= 0");
  if (!(max_l2_distance >= 0.0)) throw OptionError("mono_init.max_l2_distance", "must be >= 0");
  if (!(ratio > 0.0 && ratio <= 1.0)) throw OptionError("mono_init.ratio", "must be in (0, 1]");
  if (!(ransac_threshold_px > 0.0)) {
    throw OptionError("mono_init.ransac_threshold_px", "must be > 0");
  }
  if (!(min_parallax_deg > 0.0)) throw OptionError("mono_init.min_parallax_deg", "must be > 0");
  if (min_triangulated < 8) throw OptionError("mono_init.min_triangulated", "must be >= 8");
  if (!(homography_score_ratio >= 0.0 && homography_score_ratio <= 1.0)) {
    throw OptionError("mono_init.homography_score_ratio", "must be in [0, 1]");
  }
  if (!(ambiguity_ratio > 0.0 && ambiguity_ratio <= 1.0)) {
    throw OptionError("mono_init.ambiguity_ratio", "must be in (0, 1]");
  }
  if (!(max_reference_age_s > 0.0)) {
    throw OptionError("mono_init.max_reference_age_s", "must be > 0");
  }
  if (!(max_gyro_rotation_error_deg >= 0.0)) {
    throw OptionError("mono_init.max_gyro_rotation_error_deg", "must be >= 0");
  }
  if (!(gyro_bias_allowance_deg_s >= 0.0)) {
    throw OptionError("mono_init.gyro_bias_allowance_deg_s", "must be >= 0");
  }
  if (!(sigma0_px > 0.0)) throw OptionError("mono_init.sigma0_px", "must be > 0");
  if (!(scale_factor >= 1.0)) throw OptionError("mono_init.scale_factor", "must be >= 1");
}

namespace {

/// Rays closer than this (cosine) are too parallel to count as good points (about 0.36 deg).
constexpr double kGoodPointMaxCosParallax = 0.99998;
/// Which good point's parallax measures the reconstruction (ORB-SLAM uses the 50th largest).
constexpr std::size_t kParallaxRank = 50;
/// Candidates closer than these are the same motion for the ambiguity test.
constexpr double kSameRotationDeg = 2.0;
constexpr double kSameDirectionDeg = 10.0;

double degrees(double radians) {
  return radians * 180.0 / M_PI;
}

/// A candidate motion T_c1_c0 (translation of unit length) and how well it explains the matches.
struct Candidate {
  SE3d T_c1_c0;
  bool from_homography = false;
  int good = 0;
  double parallax_deg = 0.0;
  std::vector<std::optional<Eigen::Vector3d>> points_c0;
};

std::vector<cv::Point2d> toCv(const std::vector<Eigen::Vector2d>& points) {
  std::vector<cv::Point2d> out;
  out.reserve(points.size());
  for (const Eigen::Vector2d& p : points)
    out.emplace_back(p.x(), p.y());
  return out;
}

SE3d motionOf(const cv::Mat& R_cv, const cv::Mat& t_cv) {
  Eigen::Matrix3d R;
  Eigen::Vector3d t;
  cv::cv2eigen(R_cv, R);
  cv::cv2eigen(t_cv, t);
  const double norm = t.norm();
  return SE3d(nearestRotation(R), norm > 0.0 ? Eigen::Vector3d(t / norm) : t);
}

/// A RANSAC model of the two views: its matrix and its decompositions into motions.
struct Model {
  Eigen::Matrix3d M = Eigen::Matrix3d::Zero();
  std::vector<Candidate> candidates;
};

/// The minimal-sample RANSAC essential matrix refitted to all its inliers (eight-point least
/// squares, then projected onto the essential manifold): far less sensitive to the noise of the
/// five sampled matches.
Eigen::Matrix3d refinedEssential(const cv::Mat& E_ransac, const std::vector<cv::Point2d>& x0,
                                 const std::vector<cv::Point2d>& x1, const cv::Mat& inliers) {
  Eigen::Matrix3d E;
  cv::cv2eigen(E_ransac, E);
  std::vector<cv::Point2d> in0, in1;
  for (std::size_t i = 0; i < x0.size(); ++i) {
    if (inliers.at<std::uint8_t>(static_cast<int>(i)) != 0) {
      in0.push_back(x0[i]);
      in1.push_back(x1[i]);
    }
  }
  if (in0.size() < 8) return E;
  const cv::Mat F = cv::findFundamentalMat(in0, in1, cv::FM_8POINT);
  if (F.rows != 3 || F.cols != 3) return E;
  cv::cv2eigen(F, E);
  const Eigen::JacobiSVD<Eigen::Matrix3d> svd(E, Eigen::ComputeFullU | Eigen::ComputeFullV);
  return svd.matrixU() * Eigen::Vector3d(1.0, 1.0, 0.0).asDiagonal() * svd.matrixV().transpose();
}

/// The four (R, t) decompositions of the RANSAC essential matrix; none when RANSAC fails.
Model essentialModel(const std::vector<cv::Point2d>& x0, const std::vector<cv::Point2d>& x1,
                     double threshold) {
  cv::Mat inliers;
  const cv::Mat E_ransac = cv::findEssentialMat(x0, x1, 1.0, cv::Point2d(0.0, 0.0), cv::RANSAC,
                                                0.999, threshold, inliers);
  if (E_ransac.rows != 3 || E_ransac.cols != 3) return {};  // several solutions or none
  Model model;
  model.M = refinedEssential(E_ransac, x0, x1, inliers);
  cv::Mat E;
  cv::eigen2cv(model.M, E);
  cv::Mat R1, R2, t;
  cv::decomposeEssentialMat(E, R1, R2, t);
  for (const cv::Mat& R : {R1, R2}) {
    model.candidates.push_back({motionOf(R, t), false, 0, 0.0, {}});
    model.candidates.push_back({motionOf(R, -t), false, 0, 0.0, {}});
  }
  return model;
}

/// The decompositions of the RANSAC homography (calibrated: K = I in normalised coordinates).
Model homographyModel(const std::vector<cv::Point2d>& x0, const std::vector<cv::Point2d>& x1,
                      double threshold) {
  const cv::Mat H = cv::findHomography(x0, x1, cv::RANSAC, threshold, cv::noArray(), 2000, 0.999);
  if (H.empty()) return {};
  Model model;
  cv::cv2eigen(H, model.M);
  if (!(std::abs(model.M.determinant()) > 1e-12)) return {};
  std::vector<cv::Mat> rotations, translations, normals;
  cv::decomposeHomographyMat(H, cv::Mat::eye(3, 3, CV_64F), rotations, translations, normals);
  for (std::size_t k = 0; k < rotations.size(); ++k) {
    model.candidates.push_back({motionOf(rotations[k], translations[k]), true, 0, 0.0, {}});
  }
  return model;
}

/// ORB-SLAM-style model scores: each match adds (bound - chi^2) per direction while its chi^2
/// is within the bound (whitened by the octave sigma). Homography: transfer errors in both
/// views, bound chi^2(2 dof, 95 %). Essential: distances to the epipolar lines, accepted under
/// chi^2(1 dof, 95 %) and scored against the 2-dof bound, so both models score on one scale.
double homographyScore(const Eigen::Matrix3d& H, const TwoViewMatches& m, double focal_px,
                       const MonoInitializerOptions& options) {
  const Eigen::Matrix3d H_inv = H.inverse();
  double score = 0.0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    const Eigen::Vector3d a = H * m.x0[i].homogeneous(), b = H_inv * m.x1[i].homogeneous();
    const double s1 = optim::octaveSigmaPx(m.octave1[i], options.sigma0_px, options.scale_factor);
    const double s0 = optim::octaveSigmaPx(m.octave0[i], options.sigma0_px, options.scale_factor);
    const double chi1 = (focal_px * (a.hnormalized() - m.x1[i]) / s1).squaredNorm();
    const double chi0 = (focal_px * (b.hnormalized() - m.x0[i]) / s0).squaredNorm();
    if (chi1 < optim::kChi2Mono95) score += optim::kChi2Mono95 - chi1;
    if (chi0 < optim::kChi2Mono95) score += optim::kChi2Mono95 - chi0;
  }
  return score;
}

double essentialScore(const Eigen::Matrix3d& E, const TwoViewMatches& m, double focal_px,
                      const MonoInitializerOptions& options) {
  constexpr double kChi2OneDof95 = 3.841;
  const auto chiToLine = [&](const Eigen::Vector3d& line, const Eigen::Vector2d& x, double s) {
    const double d = focal_px * line.dot(x.homogeneous()) / line.head<2>().norm();
    return d * d / (s * s);
  };
  double score = 0.0;
  for (std::size_t i = 0; i < m.size(); ++i) {
    const double s1 = optim::octaveSigmaPx(m.octave1[i], options.sigma0_px, options.scale_factor);
    const double s0 = optim::octaveSigmaPx(m.octave0[i], options.sigma0_px, options.scale_factor);
    const double chi1 = chiToLine(E * m.x0[i].homogeneous(), m.x1[i], s1);
    const double chi0 = chiToLine(E.transpose() * m.x1[i].homogeneous(), m.x0[i], s0);
    if (chi1 < kChi2OneDof95) score += optim::kChi2Mono95 - chi1;
    if (chi0 < kChi2OneDof95) score += optim::kChi2Mono95 - chi0;
  }
  return score;
}

/// Squared reprojection error [px^2] of p_c (a camera-frame point) against normalised x.
double squaredErrorPx(const Eigen::Vector3d& p_c, const Eigen::Vector2d& x, double focal_px) {
  const Eigen::Vector2d projected = p_c.head<2>() / p_c.z();
  return (focal_px * (projected - x)).squaredNorm();
}

/// Triangulates every match with the candidate motion and counts the good points: in front of
/// both cameras, enough parallax, reprojection within the chi^2 bound in both views.
void evaluate(const TwoViewMatches& matches, double focal_px, const MonoInitializerOptions& options,
              Candidate& candidate) {
  const SE3d T_c0_c1 = candidate.T_c1_c0.inverse();
  optim::TriangulationOptions triangulation;
  triangulation.max_cos_parallax = kGoodPointMaxCosParallax;
  candidate.points_c0.assign(matches.size(), std::nullopt);
  std::vector<double> parallaxes;
  for (std::size_t i = 0; i < matches.size(); ++i) {
    const Eigen::Vector3d b0(matches.x0[i].x(), matches.x0[i].y(), 1.0);
    const Eigen::Vector3d b1(matches.x1[i].x(), matches.x1[i].y(), 1.0);
    const optim::TriangulationResult r =
        optim::triangulateTwoView(b0, SE3d(), b1, T_c0_c1, triangulation);
    if (!r.ok()) continue;
    const Eigen::Vector3d p_c1 = candidate.T_c1_c0 * r.p_w;
    if (!(r.p_w.z() > 0.0 && p_c1.z() > 0.0)) continue;
    const double s0 =
        optim::octaveSigmaPx(matches.octave0[i], options.sigma0_px, options.scale_factor);
    const double s1 =
        optim::octaveSigmaPx(matches.octave1[i], options.sigma0_px, options.scale_factor);
    if (squaredErrorPx(r.p_w, matches.x0[i], focal_px) > optim::kChi2Mono95 * s0 * s0) continue;
    if (squaredErrorPx(p_c1, matches.x1[i], focal_px) > optim::kChi2Mono95 * s1 * s1) continue;
    candidate.points_c0[i] = r.p_w;
    parallaxes.push_back(degrees(std::acos(std::clamp(r.cos_parallax, -1.0, 1.0))));
  }
  candidate.good = static_cast<int>(parallaxes.size());
  if (parallaxes.empty()) return;
  std::sort(parallaxes.begin(), parallaxes.end(), std::greater<>());
  candidate.parallax_deg = parallaxes[std::min(kParallaxRank, parallaxes.size() - 1)];
}

bool sameMotion(const SE3d& a, const SE3d& b) {
  const double rotation_deg = degrees(rotationAngle(a.rotation().transpose() * b.rotation()));
  const double direction_deg = degrees(std::acos(std::clamp(a.t.dot(b.t), -1.0, 1.0)));
  return rotation_deg < kSameRotationDeg && direction_deg < kSameDirectionDeg;
}

double medianDepth(const std::vector<std::optional<Eigen::Vector3d>>& points) {
  std::vector<double> depths;
  for (const auto& p : points)
    if (p) depths.push_back(p->z());
  const auto middle = depths.begin() + static_cast<std::ptrdiff_t>(depths.size() / 2);
  std::nth_element(depths.begin(), middle, depths.end());
  return *middle;
}

}  // namespace

TwoViewResult reconstructTwoView(const TwoViewMatches& matches, double focal_px,
                                 const MonoInitializerOptions& options) {
  options.validate();
  TwoViewResult result;
  if (static_cast<int>(matches.size()) < options.min_matches) {
    result.failure = "too few matches";
    return result;
  }
  const std::vector<cv::Point2d> x0 = toCv(matches.x0), x1 = toCv(matches.x1);
  const double threshold = options.ransac_threshold_px / focal_px;
  // Model selection as ORB-SLAM: the homography when it explains the matches nearly as well as
  // the essential matrix (planar or low-parallax scenes, where E is ill-conditioned).
  Model essential = essentialModel(x0, x1, threshold);
  Model homography = homographyModel(x0, x1, threshold);
  const double score_e =
      essential.candidates.empty() ? 0.0 : essentialScore(essential.M, matches, focal_px, options);
  const double score_h = homography.candidates.empty()
                             ? 0.0
                             : homographyScore(homography.M, matches, focal_px, options);
  const bool use_homography =
      score_h + score_e > 0.0 && score_h / (score_h + score_e) > options.homography_score_ratio;
  std::vector<Candidate> candidates =
      std::move(use_homography ? homography.candidates : essential.candidates);
  if (candidates.empty()) {
    result.failure = "no motion hypothesis";
    return result;
  }
  for (Candidate& c : candidates)
    evaluate(matches, focal_px, options, c);
  const auto best =
      std::max_element(candidates.begin(), candidates.end(),
                       [](const Candidate& a, const Candidate& b) { return a.good < b.good; });
  if (best->good < options.min_triangulated) {
    result.failure = "too few triangulated points";
    return result;
  }
  for (const Candidate& c : candidates) {
    if (!sameMotion(c.T_c1_c0, best->T_c1_c0) && c.good > options.ambiguity_ratio * best->good) {
      result.failure = "ambiguous motion";
      return result;
    }
  }
  if (best->parallax_deg < options.min_parallax_deg) {
    result.failure = "too little parallax";
    return result;
  }
  const double scale = 1.0 / medianDepth(best->points_c0);
  result.ok = true;
  result.good = best->good;
  result.parallax_deg = best->parallax_deg;
  result.from_homography = best->from_homography;
  const SE3d T_c0_c1 = best->T_c1_c0.inverse();
  result.T_c0_c1 = SE3d(T_c0_c1.q, T_c0_c1.t * scale);
  result.points_c0 = best->points_c0;
  for (auto& p : result.points_c0)
    if (p) *p *= scale;
  return result;
}

MonoInitializer::MonoInitializer(const MonoInitializerOptions& options, double focal_px)
    : options_(options), focal_px_(focal_px) {
  options_.validate();
  if (!(focal_px_ > 0.0)) throw OptionError("focal_px", "must be > 0");
}

void MonoInitializer::setReference(const Frame& frame) {
  if (static_cast<int>(frame.size()) < options_.min_features) {
    reference_.reset();
    last_failure_ = "too few features for a reference frame";
    return;
  }
  reference_ = frame;
}

std::vector<features::Match> MonoInitializer::matchToReference(const Frame& frame) const {
  std::vector<Eigen::Vector2d> predicted;
  predicted.reserve(reference_->size());
  for (const features::Keypoint& k : reference_->features.keypoints)
    predicted.push_back(k.pixel);
  features::ProjectionMatchOptions window;
  window.radius_px = options_.search_radius_px;
  window.max_distance = options_.max_distance;
  window.max_l2_distance = options_.max_l2_distance;
  window.ratio = options_.ratio;
  window.check_orientation = true;
  window.same_class_only = options_.same_class_only;
  const features::KeypointGrid grid(frame.features.keypoints, frame.features.image_size);
  std::vector<features::Match> usable;
  for (const features::Match& m :
       features::matchByProjection(reference_->features, predicted, frame.features, grid, window)) {
    if (reference_->normalized[static_cast<std::size_t>(m.query)].allFinite() &&
        frame.normalized[static_cast<std::size_t>(m.train)].allFinite()) {
      usable.push_back(m);
    }
  }
  return usable;
}

bool MonoInitializer::agreesWithGyro(const SE3d& T_c0_c1, const Eigen::Matrix3d& R_c0_c1_gyro,
                                     TimeNs t_ns) const {
  const double error_deg = degrees(rotationAngle(T_c0_c1.rotation().transpose() * R_c0_c1_gyro));
  const double dt_s = nsToSeconds(t_ns - reference_->t_ns);
  return error_deg <=
         options_.max_gyro_rotation_error_deg + options_.gyro_bias_allowance_deg_s * dt_s;
}

std::optional<MonoInitialization> MonoInitializer::addFrame(
    const Frame& frame, const std::optional<Eigen::Matrix3d>& R_c0_c1_gyro) {
  last_failure_.clear();
  if (!reference_ || frame.t_ns - reference_->t_ns > secondsToNs(options_.max_reference_age_s)) {
    setReference(frame);
    return std::nullopt;
  }
  if (frame.features.empty() || reference_->features.empty()) {
    setReference(frame);
    return std::nullopt;
  }
  const std::vector<features::Match> matches = matchToReference(frame);
  if (static_cast<int>(matches.size()) < options_.min_matches) {
    last_failure_ = "too few matches to the reference frame";
    setReference(frame);  // the view changed too much: start over from here
    return std::nullopt;
  }
  TwoViewMatches views;
  for (const features::Match& m : matches) {
    const auto r = static_cast<std::size_t>(m.query), c = static_cast<std::size_t>(m.train);
    views.x0.push_back(reference_->normalized[r]);
    views.x1.push_back(frame.normalized[c]);
    views.octave0.push_back(reference_->features.keypoints[r].octave);
    views.octave1.push_back(frame.features.keypoints[c].octave);
  }
  const TwoViewResult two_view = reconstructTwoView(views, focal_px_, options_);
  if (!two_view.ok) {
    last_failure_ = two_view.failure;
    return std::nullopt;
  }
  if (R_c0_c1_gyro && !agreesWithGyro(two_view.T_c0_c1, *R_c0_c1_gyro, frame.t_ns)) {
    last_failure_ = "rotation disagrees with the gyroscope";
    return std::nullopt;  // the reference stays: a later frame has more parallax
  }
  MonoInitialization init{*reference_, two_view.T_c0_c1, {}};
  for (std::size_t k = 0; k < matches.size(); ++k) {
    if (two_view.points_c0[k]) {
      init.points.push_back({matches[k].query, matches[k].train, *two_view.points_c0[k]});
    }
  }
  reference_.reset();
  return init;
}

}  // namespace superdyna::tracking
