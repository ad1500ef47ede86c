#include "superdyna/features/stereo_matcher.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <limits>
#include <numbers>

#include "superdyna/core/error.h"
#include "superdyna/features/matcher.h"

namespace superdyna::features {

namespace {

constexpr double kNoDistance = std::numeric_limits<double>::infinity();
/// Rays closer to parallel than this (1 - cos^2 of their angle) do not triangulate.
constexpr double kMinParallaxSin2 = 1e-12;

void requireRatio(double ratio) {
  if (!(ratio > 0.0 && ratio <= 1.0)) {
    throw OptionError("ratio", fmt::format("must be in (0, 1], got {}", ratio));
  }
}

/// Whether two keypoint angles [deg] agree within `tolerance` after removing `offset` (keypoints
/// without angle always agree).
bool anglesAgree(float left, float right, double offset, double tolerance) {
  if (left < 0.0f || right < 0.0f || tolerance >= 180.0) return true;
  double gap = std::fmod(std::abs(static_cast<double>(right) - left - offset), 360.0);
  gap = std::min(gap, 360.0 - gap);
  return gap <= tolerance;
}

void requireAngleTolerance(double degrees) {
  if (!(degrees > 0.0 && degrees <= 180.0)) {
    throw OptionError("max_angle_difference_deg",
                      fmt::format("must be in (0, 180], got {}", degrees));
  }
}

bool passesRatio(double best, double second, double ratio) {
  return ratio >= 1.0 || second == kNoDistance || best < ratio * second;
}

/// Keeps the closest match of every right keypoint (ties: the earlier); order preserved.
template <typename M>
std::vector<M> uniqueRight(const std::vector<M>& matches, std::size_t right_count) {
  std::vector<int> owner(right_count, -1);
  for (std::size_t k = 0; k < matches.size(); ++k) {
    int& slot = owner[static_cast<std::size_t>(matches[k].right)];
    if (slot < 0 || matches[k].distance < matches[static_cast<std::size_t>(slot)].distance) {
      slot = static_cast<int>(k);
    }
  }
  std::vector<M> kept;
  for (std::size_t k = 0; k < matches.size(); ++k) {
    if (owner[static_cast<std::size_t>(matches[k].right)] == static_cast<int>(k)) {
      kept.push_back(matches[k]);
    }
  }
  return kept;
}

/// Bearing of a right keypoint with its normalised image point (valid when z > 0).
struct RightBearing {
  Eigen::Vector3d f = Eigen::Vector3d::Zero();
  Eigen::Vector3d x = Eigen::Vector3d::Zero();  ///< f / f.z: (x, y, 1).
  bool valid = false;
};

/// The valid right bearings sorted by normalised y, to visit only those near an epipolar line
/// instead of all (the search was quadratic in the keypoint count).
class BearingsByRow {
 public:
  explicit BearingsByRow(const std::vector<RightBearing>& bearings) {
    for (std::size_t j = 0; j < bearings.size(); ++j) {
      if (!bearings[j].valid) continue;
      rows_.emplace_back(bearings[j].x.y(), static_cast<int>(j));
      x_min_ = std::min(x_min_, bearings[j].x.x());
      x_max_ = std::max(x_max_, bearings[j].x.x());
    }
    std::sort(rows_.begin(), rows_.end());
  }

  /// Indices (ascending) of a superset of the bearings x with |line . x| <= max_residual: those
  /// whose y lies in the band's y range over the bearings' x range.
  std::vector<int> near(const Eigen::Vector3d& line, double max_residual) const {
    std::vector<int> out;
    const double a = line.x(), b = line.y(), c = line.z();
    if (std::abs(b) < 1e-9) {  // a vertical line: no y bound
      for (const auto& row : rows_)
        out.push_back(row.second);
    } else {
      // y = (-c - a x +- r) / b, extreme at the ends of the x range; widened against rounding.
      const double margin = 1e-9 + 1e-9 * std::abs(c);
      double y_lo = std::numeric_limits<double>::infinity();
      double y_hi = -y_lo;
      for (const double x : {x_min_, x_max_}) {
        for (const double r : {-max_residual, max_residual}) {
          const double y = (-c - a * x + r) / b;
          y_lo = std::min(y_lo, y);
          y_hi = std::max(y_hi, y);
        }
      }
      const auto first =
          std::lower_bound(rows_.begin(), rows_.end(), std::make_pair(y_lo - margin, -1));
      for (auto it = first; it != rows_.end() && it->first <= y_hi + margin; ++it)
        out.push_back(it->second);
    }
    std::sort(out.begin(), out.end());  // the order of the full scan: same ties, same matches
    return out;
  }

 private:
  std::vector<std::pair<double, int>> rows_;
  double x_min_ = std::numeric_limits<double>::infinity();
  double x_max_ = -std::numeric_limits<double>::infinity();
};

}  // namespace

// ------------------------------------------------------------------------------------------------
// Unrectified stereo

void StereoMatchOptions::validate() const {
  if (!(max_epipolar_error_px > 0.0)) throw OptionError("max_epipolar_error_px", "must be > 0");
  if (max_distance < 0) throw OptionError("max_distance", "must be >= 0");
  if (!(max_l2_distance >= 0.0)) throw OptionError("max_l2_distance", "must be >= 0");
  requireRatio(ratio);
  if (max_octave_difference < 0) throw OptionError("max_octave_difference", "must be >= 0");
  requireAngleTolerance(max_angle_difference_deg);
  if (!(min_depth_m > 0.0)) throw OptionError("min_depth_m", "must be > 0");
  if (!(max_depth_m > min_depth_m)) throw OptionError("max_depth_m", "must be > min_depth_m");
  if (!(refine_max_shift > 0.0 && refine_max_shift <= 1.0)) {
    throw OptionError("refine_max_shift", "must be in (0, 1]");
  }
  if (!(check_search_px >= 0.0)) throw OptionError("check_search_px", "must be >= 0");
  if (!(check_ratio > 0.0 && check_ratio <= 1.0)) {
    throw OptionError("check_ratio", "must be in (0, 1]");
  }
}

StereoMatcher::StereoMatcher(const sensors::CameraCalibration& cam0,
                             const sensors::CameraCalibration& cam1,
                             const StereoMatchOptions& options)
    : camera0_(cam0.cameraModel()),
      camera1_(cam1.cameraModel()),
      T_c1_c0_(cam1.T_b_c.inverse() * cam0.T_b_c),
      options_(options) {
  options_.validate();
  const Eigen::Matrix3d R = T_c1_c0_.rotation();
  const Eigen::Vector3d& t = T_c1_c0_.t;
  if (!(t.norm() > 1e-9)) throw OptionError("cam1", "the stereo baseline is zero");
  essential_ = hat(t) * R;
  R_c0_c1_ = R.transpose();
  c1_in_c0_ = -(R_c0_c1_ * t);
  focal1_px_ = 0.5 * (camera1_.fx() + camera1_.fy());
  roll_deg_ = std::atan2(R(1, 0), R(0, 0)) * 180.0 / std::numbers::pi;
}

double StereoMatcher::epipolarErrorPx(const Eigen::Vector3d& f0, const Eigen::Vector3d& f1) const {
  const Eigen::Vector3d line = essential_ * f0;
  const double norm = std::hypot(line.x(), line.y());
  if (!(f1.z() > 0.0) || norm < 1e-12) return std::numeric_limits<double>::infinity();
  return std::abs(line.dot(f1 / f1.z())) / norm * focal1_px_;
}

Eigen::Vector3d StereoMatcher::ontoEpipolarLine(const Eigen::Vector3d& f0,
                                                const Eigen::Vector3d& f1) const {
  const Eigen::Vector3d line = essential_ * f0;
  const double norm2 = line.x() * line.x() + line.y() * line.y();
  if (!(f1.z() > 0.0) || norm2 < 1e-24) return f1;
  const Eigen::Vector3d x = f1 / f1.z();
  return x - line.dot(x) / norm2 * Eigen::Vector3d(line.x(), line.y(), 0.0);
}

std::optional<Eigen::Vector3d> StereoMatcher::triangulate(const Eigen::Vector3d& f0,
                                                          const Eigen::Vector3d& f1) const {
  // Closest points s * d0 and c + t * d1 of the two rays (cam0 frame), the right ray first moved
  // into the epipolar plane so that the rays meet.
  const Eigen::Vector3d d0 = f0.normalized();
  const Eigen::Vector3d d1 = (R_c0_c1_ * ontoEpipolarLine(f0, f1)).normalized();
  const double b = d0.dot(d1);
  const double denominator = 1.0 - b * b;
  if (denominator < kMinParallaxSin2) return std::nullopt;
  const double d = d0.dot(c1_in_c0_), e = d1.dot(c1_in_c0_);
  const double s = (d - b * e) / denominator;
  const double t = b * s - e;
  if (!(s > 0.0) || !(t > 0.0)) return std::nullopt;
  const Eigen::Vector3d midpoint = 0.5 * (s * d0 + c1_in_c0_ + t * d1);
  return midpoint;
}

std::vector<StereoMatch> StereoMatcher::match(const FeatureSet& left,
                                              const FeatureSet& right) const {
  const DescriptorMetric distance_of(left, right, "StereoMatcher::match");
  const double max_distance = distance_of.bound(options_.max_distance, options_.max_l2_distance);
  std::vector<RightBearing> bearings(right.size());
  for (std::size_t j = 0; j < right.size(); ++j) {
    const auto f = camera1_.unproject(right.keypoints[j].pixel);
    if (!f || !(f->z() > 0.0)) continue;
    bearings[j] = {*f, *f / f->z(), true};
  }
  const BearingsByRow rows(bearings);
  std::vector<StereoMatch> matches;
  for (std::size_t i = 0; i < left.size(); ++i) {
    const auto f0 = camera0_.unproject(left.keypoints[i].pixel);
    if (!f0) continue;
    const Eigen::Vector3d line = essential_ * *f0;
    const double line_norm = std::hypot(line.x(), line.y());
    if (line_norm < 1e-12) continue;
    const double max_residual = options_.max_epipolar_error_px / focal1_px_ * line_norm;
    const int octave = left.keypoints[i].octave;
    const int class_id = left.keypoints[i].class_id;
    double best = kNoDistance, second = kNoDistance;
    StereoMatch candidate;
    for (const int right_index : rows.near(line, max_residual)) {
      const auto j = static_cast<std::size_t>(right_index);
      const RightBearing& rb = bearings[j];
      const Keypoint& candidate_kp = right.keypoints[j];
      if (!rb.valid || std::abs(candidate_kp.octave - octave) > options_.max_octave_difference ||
          (options_.same_class_only && candidate_kp.class_id != class_id) ||
          !anglesAgree(left.keypoints[i].angle, candidate_kp.angle, roll_deg_,
                       options_.max_angle_difference_deg)) {
        continue;
      }
      const double residual = std::abs(line.dot(rb.x));
      if (residual > max_residual) continue;
      const double distance = distance_of(static_cast<int>(i), static_cast<int>(j));
      if (distance >= second) continue;  // cannot change the best two
      const auto p = triangulate(*f0, rb.f);
      if (!p || !acceptsPoint(*p)) continue;
      if (distance < best) {
        second = best;
        best = distance;
        candidate = {static_cast<int>(i),
                     static_cast<int>(j),
                     distance,
                     residual / line_norm * focal1_px_,
                     *p,
                     p->z(),
                     candidate_kp.pixel};
      } else {
        second = distance;
      }
    }
    if (candidate.right >= 0 && best <= max_distance && passesRatio(best, second, options_.ratio)) {
      matches.push_back(candidate);
    }
  }
  return uniqueRight(matches, right.size());
}

bool StereoMatcher::acceptsPoint(const Eigen::Vector3d& p_c0) const {
  return p_c0.z() >= options_.min_depth_m && p_c0.z() <= options_.max_depth_m &&
         (T_c1_c0_ * p_c0).z() > 0.0;
}

namespace {

constexpr int kSadHalfWindow = 5;  ///< 11x11 windows.
constexpr int kSadWindowSide = 2 * kSadHalfWindow + 1;
/// The gray levels of an 11x11 window, row by row.
using SadWindow = std::array<float, kSadWindowSide * kSadWindowSide>;

template <class Window>
float sumAbsoluteDifferences(const Window& a, const Window& b) {
  float sad = 0.0f;
  for (std::size_t k = 0; k < a.size(); ++k)
    sad += std::abs(a[k] - b[k]);
  return sad;
}

/// Subtracts the window's mean (summed in double, in storage order) from every sample.
template <class Window>
void subtractMean(Window& window) {
  double sum = 0.0;
  for (const float v : window)
    sum += v;
  const float mean = static_cast<float>(sum / static_cast<double>(window.size()));
  for (float& v : window)
    v -= mean;
}

/// Sub-pixel offset of the minimum of the parabola through (-1, a), (0, b), (1, c); nullopt when
/// the parabola is flat or opens downwards, or its minimum lies more than one sample away.
std::optional<double> parabolaMinimum(double a, double b, double c) {
  const double curvature = a + c - 2.0 * b;
  if (!(curvature > 0.0)) return std::nullopt;
  const double offset = (a - c) / (2.0 * curvature);
  if (std::abs(offset) > 1.0) return std::nullopt;
  return offset;
}

/// The bilinear taps of a window's 11 columns (or rows) centred at `centre`: per offset -5..5 the
/// pixel at or before it and the weight of the next one. A window's 121 samples share them.
struct WindowTaps {
  std::array<int, kSadWindowSide> pixel{};
  std::array<double, kSadWindowSide> weight{};
};

WindowTaps windowTaps(double centre) {
  WindowTaps taps;
  for (int d = -kSadHalfWindow; d <= kSadHalfWindow; ++d) {
    const double v = centre + d;
    const auto i = static_cast<std::size_t>(d + kSadHalfWindow);
    taps.pixel[i] = static_cast<int>(std::floor(v));
    taps.weight[i] = v - taps.pixel[i];
  }
  return taps;
}

/// Zero-mean 11x11 window of `image` (CV_8UC1) centred at the sub-pixel point `centre`, each
/// sample bilinear; the caller keeps the window one pixel inside the image (windowFits).
SadWindow zeroMeanWindowAt(const cv::Mat& image, const Eigen::Vector2d& centre) {
  const WindowTaps columns = windowTaps(centre.x()), rows = windowTaps(centre.y());
  SadWindow window;
  for (std::size_t r = 0; r < rows.pixel.size(); ++r) {
    const std::uint8_t* top = image.ptr<std::uint8_t>(rows.pixel[r]);
    const std::uint8_t* bottom = image.ptr<std::uint8_t>(rows.pixel[r] + 1);
    const double ay = rows.weight[r];
    for (std::size_t c = 0; c < columns.pixel.size(); ++c) {
      const int x0 = columns.pixel[c];
      const double ax = columns.weight[c];
      const double value = (1.0 - ay) * ((1.0 - ax) * top[x0] + ax * top[x0 + 1]) +
                           ay * ((1.0 - ax) * bottom[x0] + ax * bottom[x0 + 1]);
      window[r * columns.pixel.size() + c] = static_cast<float>(value);
    }
  }
  subtractMean(window);
  return window;
}

/// Whether an 11x11 window at `centre` moved by up to `reach` pixels stays inside `image` with
/// the bilinear neighbour.
bool windowFits(const cv::Mat& image, const Eigen::Vector2d& centre, double reach) {
  const double margin = kSadHalfWindow + reach + 1.0;
  return centre.x() - margin >= 0.0 && centre.y() - margin >= 0.0 &&
         centre.x() + margin <= image.cols - 1.0 && centre.y() + margin <= image.rows - 1.0;
}

/// The SAD of the left window at `centre` against right windows at `at` + k * `step`, k =
/// -reach..reach.
std::vector<float> sadsAlong(const cv::Mat& left_image, const Eigen::Vector2d& centre,
                             const cv::Mat& right_image, const Eigen::Vector2d& at,
                             const Eigen::Vector2d& step, int reach) {
  const SadWindow window = zeroMeanWindowAt(left_image, centre);
  std::vector<float> sads;
  sads.reserve(static_cast<std::size_t>(2 * reach + 1));
  for (int k = -reach; k <= reach; ++k)
    sads.push_back(sumAbsoluteDifferences(window, zeroMeanWindowAt(right_image, at + k * step)));
  return sads;
}

/// Offset [steps] from the centre of `sads` (2 * reach + 1 samples) of the sub-pixel minimum of
/// its central 2 * search + 1 samples; nullopt when that minimum lies at the end of the search or
/// the SAD curve has no parabolic minimum there.
std::optional<double> sadMinimumWithin(const std::vector<float>& sads, int search) {
  const long reach = static_cast<long>(sads.size() / 2);
  const auto first = sads.begin() + (reach - search), last = sads.begin() + (reach + search + 1);
  const auto best = std::min_element(first, last);
  if (best == first || best + 1 == last) return std::nullopt;
  const auto offset = parabolaMinimum(*(best - 1), *best, *(best + 1));
  if (!offset) return std::nullopt;
  return static_cast<double>(best - sads.begin() - reach) + *offset;
}

/// Whether a window outside the central 2 * search + 1 samples of `sads` matches better than
/// `ratio` times the best one inside: the descriptor match likely paired the left keypoint with a
/// right neighbour of its own point (absent from the right keypoints) or a repetition.
bool betterWindowOutside(const std::vector<float>& sads, int search, double ratio) {
  const long reach = static_cast<long>(sads.size() / 2);
  const auto first = sads.begin() + (reach - search), last = sads.begin() + (reach + search + 1);
  const float inside = *std::min_element(first, last);
  const float outside =
      std::min(first == sads.begin() ? inside : *std::min_element(sads.begin(), first),
               last == sads.end() ? inside : *std::min_element(last, sads.end()));
  return outside < ratio * inside;
}

}  // namespace

std::optional<StereoMatch> StereoMatcher::refined(const StereoMatch& match,
                                                  const Keypoint& left_keypoint,
                                                  const cv::Mat& left_image,
                                                  const cv::Mat& right_image, int search_px) const {
  const Eigen::Vector2d centre(std::round(left_keypoint.pixel.x()),
                               std::round(left_keypoint.pixel.y()));
  const auto f_centre = camera0_.unproject(centre);
  const auto f_keypoint = camera0_.unproject(left_keypoint.pixel);
  if (!f_centre || !f_keypoint || !windowFits(left_image, centre, 0.0)) return match;
  // The epipolar curve near the match: the window centre's ray at the match depth, and nearer.
  const Eigen::Vector3d p_centre = *f_centre * (match.depth_m / f_centre->z());
  const auto at = camera1_.project(T_c1_c0_ * p_centre);
  const auto nearer = camera1_.project(T_c1_c0_ * (0.5 * p_centre));
  if (!at || !nearer || !windowFits(right_image, *at, search_px)) return match;
  const Eigen::Vector2d step = (*at - *nearer).normalized();  // towards smaller disparity
  const int check = static_cast<int>(std::ceil(options_.check_search_px));
  const int reach = check > search_px && windowFits(right_image, *at, check) ? check : search_px;
  const std::vector<float> sads = sadsAlong(left_image, centre, right_image, *at, step, reach);
  if (betterWindowOutside(sads, search_px, options_.check_ratio)) return std::nullopt;
  const auto offset = sadMinimumWithin(sads, search_px);
  // A minimum far out in the search is more often another repetition of the texture or the far
  // side of a depth edge than the keypoints' point (measured: see refine_max_shift).
  if (!offset || std::abs(*offset) > options_.refine_max_shift * search_px) return match;
  const Eigen::Vector2d right_centre = *at + *offset * step;
  const auto f_right = camera1_.unproject(right_centre);
  if (!f_right) return std::nullopt;
  const auto p = triangulate(*f_centre, *f_right);
  if (!p) return std::nullopt;
  StereoMatch out = match;
  out.p_c0 = *f_keypoint * (p->z() / f_keypoint->z());  // the keypoint's own ray, that depth
  out.depth_m = out.p_c0.z();
  if (!acceptsPoint(out.p_c0)) return std::nullopt;
  const auto right_pixel = camera1_.project(T_c1_c0_ * out.p_c0);
  if (!right_pixel) return std::nullopt;
  out.right_pixel = *right_pixel;
  return out;
}

std::vector<StereoMatch> StereoMatcher::match(const FeatureSet& left, const FeatureSet& right,
                                              const cv::Mat& left_image, const cv::Mat& right_image,
                                              double level_scale_factor) const {
  if (!(level_scale_factor >= 1.0)) {
    throw OptionError("level_scale_factor",
                      fmt::format("must be >= 1, got {}", level_scale_factor));
  }
  for (const auto& [image, features] : {std::pair{&left_image, &left}, {&right_image, &right}}) {
    if (image->type() != CV_8UC1 || image->size() != features->image_size) {
      throw InputError(fmt::format(
          "StereoMatcher::match: images must be CV_8UC1 of the features' size {}x{}, got {}x{}",
          features->image_size.width, features->image_size.height, image->cols, image->rows));
    }
  }
  std::vector<StereoMatch> out;
  for (const StereoMatch& m : match(left, right)) {
    const Keypoint& kp = left.keypoints[static_cast<std::size_t>(m.left)];
    const int search =
        static_cast<int>(std::ceil(std::pow(level_scale_factor, std::max(0, kp.octave)))) + 1;
    const auto r = refined(m, kp, left_image, right_image, search);
    if (r) out.push_back(*r);
  }
  return out;
}

// ------------------------------------------------------------------------------------------------
// Rectified stereo

namespace {

/// Zero-mean window of `image` centred at (x, y), as floats (row-major).
std::vector<float> zeroMeanWindow(const cv::Mat& image, int x, int y, int half) {
  std::vector<float> window;
  window.reserve(static_cast<std::size_t>((2 * half + 1) * (2 * half + 1)));
  for (int dy = -half; dy <= half; ++dy) {
    const std::uint8_t* row = image.ptr<std::uint8_t>(y + dy);
    for (int dx = -half; dx <= half; ++dx)
      window.push_back(row[x + dx]);
  }
  subtractMean(window);
  return window;
}

struct Refinement {
  double u_right;      ///< Refined right column of the left window's centre column [px].
  double left_column;  ///< Column of the left window's centre [px].
  float sad;           ///< Mean absolute difference at the best integer offset.
};

/// SAD search along the row around right column `u_right`, for the left window at (u, v).
std::optional<Refinement> refineBySad(const cv::Mat& left, const cv::Mat& right,
                                      const Eigen::Vector2d& left_pixel, double u_right,
                                      const RectifiedStereoOptions& options) {
  const int half = options.sad_half_window, search = options.sad_search_px;
  const int xl = static_cast<int>(std::lround(left_pixel.x()));
  const int y = static_cast<int>(std::lround(left_pixel.y()));
  const int xr = static_cast<int>(std::lround(u_right));
  if (y - half < 0 || y + half >= left.rows || xl - half < 0 || xl + half >= left.cols ||
      xr - search - half < 0 || xr + search + half >= right.cols) {
    return std::nullopt;
  }
  const std::vector<float> window = zeroMeanWindow(left, xl, y, half);
  std::vector<float> sads;
  for (int k = -search; k <= search; ++k)
    sads.push_back(sumAbsoluteDifferences(window, zeroMeanWindow(right, xr + k, y, half)));
  const auto best = std::min_element(sads.begin(), sads.end());
  const long at = best - sads.begin();
  if (at == 0 || at + 1 == static_cast<long>(sads.size())) return std::nullopt;  // at the edge
  const auto offset = parabolaMinimum(sads[static_cast<std::size_t>(at - 1)], *best,
                                      sads[static_cast<std::size_t>(at + 1)]);
  if (!offset) return std::nullopt;
  return Refinement{xr + static_cast<double>(at - search) + *offset, static_cast<double>(xl),
                    *best / static_cast<float>(window.size())};
}

}  // namespace

void RectifiedStereoOptions::validate() const {
  if (!(row_tolerance_px >= 0.0)) throw OptionError("row_tolerance_px", "must be >= 0");
  if (!(level_scale_factor >= 1.0)) throw OptionError("level_scale_factor", "must be >= 1");
  if (max_distance < 0) throw OptionError("max_distance", "must be >= 0");
  if (!(max_l2_distance >= 0.0)) throw OptionError("max_l2_distance", "must be >= 0");
  requireRatio(ratio);
  if (max_octave_difference < 0) throw OptionError("max_octave_difference", "must be >= 0");
  requireAngleTolerance(max_angle_difference_deg);
  if (!(min_depth_m > 0.0)) throw OptionError("min_depth_m", "must be > 0");
  if (!(max_depth_m > min_depth_m)) throw OptionError("max_depth_m", "must be > min_depth_m");
  if (sad_half_window < 1) throw OptionError("sad_half_window", "must be >= 1");
  if (sad_search_px < 1) throw OptionError("sad_search_px", "must be >= 1");
  if (!(sad_outlier_factor >= 0.0)) throw OptionError("sad_outlier_factor", "must be >= 0");
}

RectifiedStereoMatcher::RectifiedStereoMatcher(double fx, double baseline_m,
                                               const RectifiedStereoOptions& options)
    : fx_(fx), baseline_m_(baseline_m), options_(options) {
  if (!(fx > 0.0)) throw OptionError("fx", "must be > 0");
  if (!(baseline_m > 0.0)) throw OptionError("baseline", "must be > 0");
  options_.validate();
}

std::vector<RectifiedStereoMatch> RectifiedStereoMatcher::match(const cv::Mat& left_image,
                                                                const cv::Mat& right_image,
                                                                const FeatureSet& left,
                                                                const FeatureSet& right) const {
  const DescriptorMetric distance_of(left, right, "RectifiedStereoMatcher::match");
  const double max_distance = distance_of.bound(options_.max_distance, options_.max_l2_distance);
  for (const cv::Mat* image : {&left_image, &right_image}) {
    if (image->type() != CV_8UC1 || image->size() != left.image_size ||
        image->size() != right.image_size) {
      throw InputError(
          fmt::format("RectifiedStereoMatcher::match: images must be CV_8UC1 of the "
                      "features' size {}x{}",
                      left.image_size.width, left.image_size.height));
    }
  }
  const double min_disparity = fx_ * baseline_m_ / options_.max_depth_m;
  const double max_disparity = fx_ * baseline_m_ / options_.min_depth_m;
  // Right keypoints sorted by row for the band search.
  std::vector<int> by_row(right.size());
  for (std::size_t j = 0; j < by_row.size(); ++j)
    by_row[j] = static_cast<int>(j);
  std::stable_sort(by_row.begin(), by_row.end(), [&](int a, int b) {
    return right.keypoints[static_cast<std::size_t>(a)].pixel.y() <
           right.keypoints[static_cast<std::size_t>(b)].pixel.y();
  });
  const auto row_of = [&](int j) { return right.keypoints[static_cast<std::size_t>(j)].pixel.y(); };

  std::vector<RectifiedStereoMatch> matches;
  for (std::size_t i = 0; i < left.size(); ++i) {
    const Keypoint& kp = left.keypoints[i];
    const double tolerance =
        options_.row_tolerance_px * std::pow(options_.level_scale_factor, kp.octave);
    auto it = std::lower_bound(by_row.begin(), by_row.end(), kp.pixel.y() - tolerance,
                               [&](int j, double v) { return row_of(j) < v; });
    double best = kNoDistance, second = kNoDistance;
    int best_j = -1;
    for (; it != by_row.end() && row_of(*it) <= kp.pixel.y() + tolerance; ++it) {
      const Keypoint& candidate = right.keypoints[static_cast<std::size_t>(*it)];
      const double disparity = kp.pixel.x() - candidate.pixel.x();
      if (std::abs(candidate.octave - kp.octave) > options_.max_octave_difference ||
          disparity < min_disparity || disparity > max_disparity ||
          !anglesAgree(kp.angle, candidate.angle, 0.0, options_.max_angle_difference_deg)) {
        continue;
      }
      const double distance = distance_of(static_cast<int>(i), *it);
      if (distance < best || (distance == best && *it < best_j)) {
        second = best;
        best = distance;
        best_j = *it;
      } else if (distance < second) {
        second = distance;
      }
    }
    if (best_j < 0 || best > max_distance || !passesRatio(best, second, options_.ratio)) {
      continue;
    }
    const auto refined =
        refineBySad(left_image, right_image, kp.pixel,
                    right.keypoints[static_cast<std::size_t>(best_j)].pixel.x(), options_);
    if (!refined) continue;
    const double disparity = refined->left_column - refined->u_right;
    if (disparity < min_disparity || disparity > max_disparity || !(disparity > 0.0)) continue;
    matches.push_back({static_cast<int>(i), best_j, best, refined->u_right, disparity,
                       fx_ * baseline_m_ / disparity, refined->sad});
  }
  matches = uniqueRight(matches, right.size());
  if (options_.sad_outlier_factor > 0.0 && !matches.empty()) {
    std::vector<float> sads;
    for (const auto& m : matches)
      sads.push_back(m.sad);
    std::nth_element(sads.begin(), sads.begin() + static_cast<long>(sads.size() / 2), sads.end());
    const double limit = options_.sad_outlier_factor * sads[sads.size() / 2];
    std::erase_if(matches, [&](const RectifiedStereoMatch& m) { return m.sad > limit; });
  }
  return matches;
}

}  // namespace superdyna::features
