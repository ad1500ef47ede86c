#include "superdyna/io/kitti_dataset.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <cmath>
#include <map>
#include <opencv2/imgcodecs.hpp>

#include "superdyna/core/error.h"
#include "superdyna/io/text_table.h"
#include "superdyna/io/trajectory_io.h"

namespace superdyna::io {

namespace fs = std::filesystem;

namespace {

using Projection = Eigen::Matrix<double, 3, 4>;

constexpr TimeNs kDefaultFramePeriodNs = 100 * kNsPerMillisecond;  // KITTI records at 10 Hz

/// Which folders hold the left/right images and which projection matrices belong to them.
struct CameraLayout {
  std::string left_folder;
  std::string right_folder;
  int left_index = 0;   ///< P<left_index> in calib.txt.
  int right_index = 1;  ///< P<right_index> in calib.txt.
};

CameraLayout findCameraLayout(const fs::path& dir) {
  static const std::array<CameraLayout, 3> kLayouts = {{
      {"image_0", "image_1", 0, 1},  // grayscale pair
      {"image_2", "image_3", 2, 3},  // colour pair
      {"image_l", "image_r", 0, 1},  // reduced excerpts: grayscale pair renamed
  }};
  for (const CameraLayout& layout : kLayouts) {
    if (fs::is_directory(dir / layout.left_folder)) return layout;
  }
  throw InputError(InputLocation{dir},
                   "not a KITTI sequence: no image_0/, image_2/ or image_l/ folder of images");
}

/// The PNG files of `folder`, sorted by name (KITTI names them 000000.png, 000001.png, ...).
std::vector<fs::path> listImages(const fs::path& folder) {
  std::vector<fs::path> images;
  for (const fs::directory_entry& entry : fs::directory_iterator(folder)) {
    if (entry.is_regular_file() && entry.path().extension() == ".png") {
      images.push_back(entry.path());
    }
  }
  std::sort(images.begin(), images.end());
  if (images.empty()) throw InputError(InputLocation{folder}, "no .png images in the folder");
  return images;
}

/// Right images must pair one-to-one with the left ones, by file name.
void requireMatchingNames(const std::vector<fs::path>& left, const std::vector<fs::path>& right,
                          const fs::path& right_folder) {
  for (std::size_t i = 0; i < std::max(left.size(), right.size()); ++i) {
    if (i < left.size() && i < right.size() && left[i].filename() == right[i].filename()) continue;
    throw InputError(InputLocation{right_folder},
                     fmt::format("right images do not match the left ones ({} vs {} images; first "
                                 "difference at image {}: '{}' vs '{}')",
                                 left.size(), right.size(), i,
                                 i < left.size() ? left[i].filename().string() : "",
                                 i < right.size() ? right[i].filename().string() : ""));
  }
}

/// "P2:" -> 2; nullopt for other labels ("Tr:", "R0_rect:"), which are skipped.
std::optional<int> projectionIndex(const std::string& label) {
  if (label.size() == 3 && label[0] == 'P' && label[1] >= '0' && label[1] <= '3' && label[2] == ':')
    return label[1] - '0';
  return std::nullopt;
}

bool isLabelled(const TextRow& row) {
  return !row.fields.empty() && row.fields.front().ends_with(':');
}

/// The projection matrices of calib.txt by camera index. Rows are either all labelled ("P0: ...")
/// or all unlabelled (12 numbers, in the order P0, P1, ...); a mix is ambiguous and rejected.
std::map<int, Projection> readProjections(const fs::path& calib) {
  const std::vector<TextRow> rows = readTextRows(calib, Delimiter::kWhitespace);
  if (rows.empty()) throw InputError(InputLocation{calib}, "no projection matrices found");
  const bool labelled = isLabelled(rows.front());
  std::map<int, Projection> projections;
  int unlabelled_index = 0;
  for (const TextRow& row : rows) {
    if (isLabelled(row) != labelled) {
      throw InputError(row.at(calib), "mixes labelled ('P0: ...') and unlabelled rows");
    }
    if (!labelled) {
      requireFieldCount(row, calib, 12, 12);
      projections[unlabelled_index++] = parseRowMajor3x4(row, calib);
    } else if (const auto index = projectionIndex(row.fields.front())) {
      requireFieldCount(row, calib, 13, 13);
      projections[*index] = parseRowMajor3x4(row, calib, 1);
    }
  }
  return projections;
}

/// A rectified projection matrix K [I | t]: zero skew, last row of K = (0 0 1), positive focal
/// lengths. Anything else is not what a KITTI odometry calib.txt holds.
void requireRectifiedProjection(const Projection& P, const InputLocation& where) {
  const bool rectified = P(0, 1) == 0.0 && P(1, 0) == 0.0 && P(2, 0) == 0.0 && P(2, 1) == 0.0 &&
                         P(2, 2) == 1.0 && P(0, 0) > 0.0 && P(1, 1) > 0.0;
  if (!rectified) {
    throw InputError(where,
                     "not a rectified projection matrix [fx 0 cx tx; 0 fy cy ty; 0 0 1 tz] "
                     "with positive focal lengths");
  }
}

const Projection& requireProjection(const std::map<int, Projection>& projections, int index,
                                    const fs::path& calib) {
  const auto it = projections.find(index);
  const InputLocation where{calib, 0, fmt::format("P{}", index)};
  if (it == projections.end()) throw InputError(where, "missing projection matrix");
  requireRectifiedProjection(it->second, where);
  return it->second;
}

/// The translation t of P = K [I | t]: from the rectified reference camera to this camera.
Eigen::Vector3d projectionTranslation(const Projection& P) {
  const double tz = P(2, 3);
  return {(P(0, 3) - P(0, 2) * tz) / P(0, 0), (P(1, 3) - P(1, 2) * tz) / P(1, 1), tz};
}

sensors::CameraCalibration calibrationFromProjection(const Projection& P, const std::string& name) {
  sensors::CameraCalibration calibration;
  calibration.name = name;
  calibration.fx = P(0, 0);
  calibration.fy = P(1, 1);
  calibration.cx = P(0, 2);
  calibration.cy = P(1, 2);
  calibration.distortion_model = DistortionModel::kNone;  // KITTI images are rectified
  return calibration;
}

/// Timestamps from times.txt, or i * 0.1 s when the file is absent.
std::vector<TimeNs> frameTimes(const fs::path& times_file, std::size_t image_count,
                               const fs::path& image_folder, std::vector<std::string>& warnings) {
  if (!fs::exists(times_file)) {
    warnings.push_back(
        fmt::format("{} not found: timestamps default to i * 0.1 s (10 Hz)", times_file.string()));
    std::vector<TimeNs> times(image_count);
    for (std::size_t i = 0; i < image_count; ++i) {
      times[i] = static_cast<TimeNs>(i) * kDefaultFramePeriodNs;
    }
    return times;
  }
  std::vector<TimeNs> times = readTimesFile(times_file);
  if (times.size() != image_count) {
    throw InputError(InputLocation{times_file},
                     fmt::format("{} timestamps but {} images in {}", times.size(), image_count,
                                 image_folder.string()));
  }
  return times;
}

double frameRateHz(const std::vector<TimeNs>& times) {
  if (times.size() < 2 || times.back() <= times.front())
    return 1.0 / nsToSeconds(kDefaultFramePeriodNs);
  return static_cast<double>(times.size() - 1) / nsToSeconds(times.back() - times.front());
}

cv::Size imageSizeOf(const fs::path& image) {
  const cv::Mat decoded = cv::imread(image.string(), cv::IMREAD_GRAYSCALE);
  if (decoded.empty()) {
    throw InputError(InputLocation{image},
                     "cannot decode the image (corrupt, truncated or not an image format)");
  }
  return decoded.size();
}

Trajectory readGroundTruth(const fs::path& poses, const fs::path& times_file,
                           std::size_t image_count) {
  TrajectoryReadOptions options;
  options.format = TrajectoryFormat::kKitti;
  if (fs::exists(times_file)) options.kitti_times = times_file;
  Trajectory trajectory = readTrajectory(poses, options);
  if (trajectory.size() != image_count) {
    throw InputError(InputLocation{poses}, fmt::format("{} poses but {} images (one pose per image "
                                                       "expected)",
                                                       trajectory.size(), image_count));
  }
  return trajectory;
}

std::vector<ImageRef> framesOf(const std::vector<fs::path>& images,
                               const std::vector<TimeNs>& times) {
  std::vector<ImageRef> frames;
  for (std::size_t i = 0; i < images.size(); ++i)
    frames.push_back({times[i], images[i]});
  return frames;
}

/// Stereo pairs when the right folder exists; empty otherwise.
std::vector<StereoFrameRef> stereoFramesOf(const fs::path& right_folder,
                                           const std::vector<fs::path>& left_images,
                                           const std::vector<TimeNs>& times) {
  if (!fs::is_directory(right_folder)) return {};
  const std::vector<fs::path> right_images = listImages(right_folder);
  requireMatchingNames(left_images, right_images, right_folder);
  std::vector<StereoFrameRef> frames;
  for (std::size_t i = 0; i < left_images.size(); ++i)
    frames.push_back({times[i], left_images[i], right_images[i]});
  return frames;
}

/// The left camera: intrinsics from its projection matrix, size of the first image.
sensors::CameraCalibration leftCalibrationOf(const std::map<int, Projection>& projections,
                                             const CameraLayout& layout,
                                             const fs::path& first_image,
                                             const std::vector<TimeNs>& times,
                                             const fs::path& calib) {
  sensors::CameraCalibration left = calibrationFromProjection(
      requireProjection(projections, layout.left_index, calib), layout.left_folder);
  const cv::Size size = imageSizeOf(first_image);
  left.width = size.width;
  left.height = size.height;
  left.rate_hz = frameRateHz(times);
  validateCameraCalibration(left, InputLocation{calib});
  return left;
}

/// The right camera when calib.txt has its projection matrix, posed in the left camera frame.
std::optional<sensors::CameraCalibration> rightCalibrationOf(
    const std::map<int, Projection>& projections, const CameraLayout& layout,
    const sensors::CameraCalibration& left, const fs::path& calib) {
  if (!projections.contains(layout.right_index)) return std::nullopt;
  const Projection& P_left = projections.at(layout.left_index);
  const Projection& P_right = requireProjection(projections, layout.right_index, calib);
  sensors::CameraCalibration right = calibrationFromProjection(P_right, layout.right_folder);
  right.width = left.width;
  right.height = left.height;
  right.rate_hz = left.rate_hz;
  // The centre of camera i in the reference frame is -t_i, so the right camera sits at
  // t_left - t_right in the left camera frame.
  right.T_b_c.t = projectionTranslation(P_left) - projectionTranslation(P_right);
  return right;
}

}  // namespace

KittiDataset KittiDataset::open(const fs::path& dir, const std::optional<fs::path>& poses_file) {
  if (!fs::is_directory(dir)) throw InputError(InputLocation{dir}, "dataset folder does not exist");
  KittiDataset dataset;
  dataset.root_ = dir;
  const CameraLayout layout = findCameraLayout(dir);
  const std::vector<fs::path> left_images = listImages(dir / layout.left_folder);

  const fs::path times_file = dir / "times.txt";
  dataset.has_times_file_ = fs::exists(times_file);
  const std::vector<TimeNs> times =
      frameTimes(times_file, left_images.size(), dir / layout.left_folder, dataset.warnings_);
  dataset.left_frames_ = framesOf(left_images, times);
  dataset.stereo_frames_ = stereoFramesOf(dir / layout.right_folder, left_images, times);

  const fs::path calib = dir / "calib.txt";
  if (!fs::exists(calib)) throw InputError(InputLocation{calib}, "file does not exist");
  const std::map<int, Projection> projections = readProjections(calib);
  dataset.left_ = leftCalibrationOf(projections, layout, left_images.front(), times, calib);
  dataset.right_ = rightCalibrationOf(projections, layout, dataset.left_, calib);
  if (dataset.isStereo() && !dataset.right_) {
    throw InputError(InputLocation{calib, 0, fmt::format("P{}", layout.right_index)},
                     "missing projection matrix of the right camera");
  }

  const fs::path poses = poses_file.value_or(dir / "poses.txt");
  if (poses_file || fs::exists(poses)) {
    dataset.ground_truth_ = readGroundTruth(poses, times_file, left_images.size());
  }
  return dataset;
}

std::optional<double> KittiDataset::baseline() const {
  if (!right_) return std::nullopt;
  return right_->T_b_c.t.x();
}

}  // namespace superdyna::io
