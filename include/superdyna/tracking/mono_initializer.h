#pragma once
// Two-view monocular initialisation (the idea of ORB-SLAM's Initializer, written anew):
//
//  1. A reference frame is kept until a later frame has enough matches to it. Matches come from a
//     window search around the reference keypoint positions (the camera moves little between the
//     two views), with the ratio and rotation-consistency checks; with same_class_only only
//     keypoints of one semantic class (class_id) are paired.
//  2. A RANSAC essential matrix (general scenes) and a RANSAC homography (planar or nearly planar
//     scenes) are estimated on undistorted normalised coordinates; ORB-SLAM's score ratio picks
//     one. Each of its decompositions (four of E, up to four of H) triangulates all matches; the
//     one with most points that lie in front of both cameras and reproject within the chi^2 bound
//     wins, provided no clearly different decomposition comes close (ambiguity) and the parallax
//     of its points is large enough.
//  3. The scale is fixed by setting the median depth of the points in the reference camera to 1.
//
// Frames: c0 = reference camera, c1 = current camera; T_c0_c1 maps c1-coordinates into c0.
// OpenCV's RANSAC (findEssentialMat, findHomography) seeds its own generator with a constant, so
// the result is deterministic.

#include <Eigen/Core>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/features/matcher.h"
#include "superdyna/tracking/frame.h"

namespace superdyna::tracking {

struct MonoInitializerOptions {
  int min_features = 100;            ///< Keypoints a reference frame needs, >= 8.
  int min_matches = 100;             ///< Matches to the reference needed to try, >= 8.
  double search_radius_px = 100.0;   ///< Window around the reference keypoint positions [px], > 0.
  int max_distance = 50;             ///< Hamming distance bound of the matches [bits], >= 0.
  double max_l2_distance = 0.9;      ///< ... Euclidean bound (float descriptors), >= 0.
  double ratio = 0.9;                ///< Best / second-best distance in the window, (0, 1].
  double ransac_threshold_px = 1.5;  ///< RANSAC inlier distance (E: Sampson, H: transfer) [px].
  double min_parallax_deg = 1.0;     ///< Parallax of the 50th largest good point [deg], > 0.
  int min_triangulated = 50;         ///< Good points the winning motion needs, >= 8.
  /// The homography is used when score_H / (score_H + score_E) exceeds this, [0, 1].
  double homography_score_ratio = 0.45;
  /// Another, clearly different motion with more than this share of the winner's good points
  /// makes the reconstruction ambiguous, (0, 1].
  double ambiguity_ratio = 0.75;
  /// A reference older than this without initialisation is replaced by the current frame [s].
  double max_reference_age_s = 1.0;
  /// With an IMU: the two-view rotation may differ from the gyroscope's (integrated at the current
  /// bias guess) by at most max_gyro_rotation_error_deg + gyro_bias_allowance_deg_s * (time
  /// between the views) [deg], [deg/s], >= 0. A low-parallax reconstruction that explains the
  /// flow with a wrong rotation (on a street one frame after the reference: 1.5 deg off, the
  /// homography chosen) is refused and the next frame tried; the allowance covers the bias.
  double max_gyro_rotation_error_deg = 0.5;
  double gyro_bias_allowance_deg_s = 5.0;
  double sigma0_px = 1.0;     ///< Keypoint standard deviation at octave 0 [px], > 0.
  double scale_factor = 1.2;  ///< Pyramid scale between octaves, >= 1 (1: one level).
  /// Match only keypoints of one class_id (the System sets it from features.class_wise_matching).
  bool same_class_only = false;

  /// Throws OptionError naming the first invalid field (prefix "mono_init.").
  void validate() const;
  bool operator==(const MonoInitializerOptions&) const = default;
};

/// Correspondences between two views in undistorted normalised coordinates, with the keypoint
/// octaves (for the chi^2 bound of the reprojection error).
struct TwoViewMatches {
  std::vector<Eigen::Vector2d> x0, x1;  ///< Normalised coordinates in view 0 and view 1.
  std::vector<int> octave0, octave1;
  std::size_t size() const { return x0.size(); }
};

/// The reconstruction of two views.
struct TwoViewResult {
  bool ok = false;
  std::string failure;  ///< Why it failed (empty when ok).
  SE3d T_c0_c1;         ///< Pose of view 1 in view 0, translation scaled as the points.
  /// Per correspondence: the point in view 0 (median depth 1), or nullopt when not good.
  std::vector<std::optional<Eigen::Vector3d>> points_c0;
  int good = 0;                  ///< Good points (with a value in points_c0).
  double parallax_deg = 0.0;     ///< Parallax measure of the good points (see options).
  bool from_homography = false;  ///< Whether the homography gave the winning motion.
};

/// Estimates the relative motion of two views and triangulates the correspondences. focal_px
/// converts normalised errors to pixels. Validates the options (OptionError).
TwoViewResult reconstructTwoView(const TwoViewMatches& matches, double focal_px,
                                 const MonoInitializerOptions& options);

/// A successful initialisation: the two frames, the matched keypoint pairs and their points.
struct MonoInitialization {
  Frame reference;
  SE3d T_c0_c1;  ///< Pose of the current camera in the reference camera (median depth 1).
  struct Point {
    int reference_index = -1;  ///< Keypoint in the reference frame.
    int current_index = -1;    ///< Keypoint in the current frame.
    Eigen::Vector3d p_c0;      ///< Position in the reference camera frame.
  };
  std::vector<Point> points;
};

class MonoInitializer {
 public:
  /// focal_px: mean focal length of cam0. Validates the options (OptionError).
  MonoInitializer(const MonoInitializerOptions& options, double focal_px);

  /// Feeds one frame: it becomes the reference when there is none (or the reference is too old
  /// or has too few matches left); otherwise the two views are reconstructed. Returns the
  /// initialisation when it succeeded (the reference is then cleared).
  /// R_c0_c1_gyro: the rotation from the reference camera to the current one by the gyroscope
  /// (when there is an IMU and a reference); a reconstruction disagreeing with it is refused.
  std::optional<MonoInitialization> addFrame(
      const Frame& frame, const std::optional<Eigen::Matrix3d>& R_c0_c1_gyro = std::nullopt);

  void reset() { reference_.reset(); }
  bool hasReference() const { return reference_.has_value(); }
  /// Time of the reference frame (only with hasReference()).
  TimeNs referenceTime() const { return reference_->t_ns; }
  /// Why the last attempt failed ("" after success or when there was nothing to try).
  const std::string& lastFailure() const { return last_failure_; }

 private:
  std::vector<features::Match> matchToReference(const Frame& frame) const;
  void setReference(const Frame& frame);
  bool agreesWithGyro(const SE3d& T_c0_c1, const Eigen::Matrix3d& R_c0_c1_gyro, TimeNs t_ns) const;

  MonoInitializerOptions options_;
  double focal_px_;
  std::optional<Frame> reference_;
  std::string last_failure_;
};

}  // namespace superdyna::tracking
