#include "superdyna/io/euroc_dataset.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <charconv>
#include <cmath>
#include <cstdlib>
#include <iterator>
#include <opencv2/imgcodecs.hpp>
#include <optional>
#include <set>
#include <system_error>
#include <utility>

#include "superdyna/core/error.h"
#include "superdyna/io/text_table.h"

namespace superdyna::io {

namespace fs = std::filesystem;

namespace {

/// IMU gaps longer than this many nominal periods are reported: a few dropped samples are common,
/// longer gaps degrade preintegration and are worth knowing about.
constexpr double kImuGapWarningPeriods = 5.0;

/// One row of a camera's data.csv, with its line for error messages.
struct ListedImage {
  ImageRef ref;
  int line = 0;
};

struct CameraList {
  fs::path csv;
  std::vector<ListedImage> images;
};

/// Frames of the two cameras matched by exact timestamp, and those left over on either side.
struct StereoMatch {
  std::vector<std::pair<const ListedImage*, const ListedImage*>> pairs;
  std::vector<const ListedImage*> cam0_only;
  std::vector<const ListedImage*> cam1_only;
};

/// Counts IMU gaps longer than the warning threshold and remembers the largest.
struct ImuGaps {
  int count = 0;
  TimeNs largest_ns = 0;
  int largest_line = 0;

  void note(TimeNs dt_ns, TimeNs threshold_ns, int line) {
    if (dt_ns <= threshold_ns) return;
    ++count;
    if (dt_ns > largest_ns) {
      largest_ns = dt_ns;
      largest_line = line;
    }
  }
};

struct GroundTruthRows {
  std::vector<sensors::GroundTruthState> states;
  bool full_state = false;
};

/// "5, 7-9, 12" (defined below).
std::string lineRuns(const std::vector<int>& lines, std::size_t max_runs);

/// Rows of a sensor stream whose timestamps do not increase, as drivers produce them: rows out of
/// order are put back in time order, and of rows with one timestamp only the first is kept. Both
/// are reported in `warnings`, naming the file and lines; nothing else changes.
template <class Row, class TimeOf>
std::vector<Row> inTimeOrder(std::vector<Row> rows, TimeOf time_of, const fs::path& csv,
                             std::vector<std::string>& warnings) {
  std::vector<int> late;
  for (std::size_t k = 1, latest = 0; k < rows.size(); ++k) {
    if (time_of(rows[k]) < time_of(rows[latest])) {
      late.push_back(rows[k].line);
    } else {
      latest = k;
    }
  }
  if (!late.empty()) {
    std::stable_sort(rows.begin(), rows.end(),
                     [&](const Row& a, const Row& b) { return time_of(a) < time_of(b); });
    warnings.push_back(fmt::format("{}: {} row(s) out of time order put back in order (lines {})",
                                   csv.string(), late.size(), lineRuns(late, 5)));
  }
  std::vector<int> repeated;
  std::vector<Row> kept;
  kept.reserve(rows.size());
  for (Row& row : rows) {
    if (!kept.empty() && time_of(row) == time_of(kept.back())) {
      repeated.push_back(row.line);
      continue;
    }
    kept.push_back(std::move(row));
  }
  if (!repeated.empty()) {
    std::sort(repeated.begin(), repeated.end());
    warnings.push_back(
        fmt::format("{}: {} row(s) repeating an earlier row's timestamp skipped (lines {})",
                    csv.string(), repeated.size(), lineRuns(repeated, 5)));
  }
  return kept;
}

fs::path findMav0(const fs::path& path) {
  if (!fs::is_directory(path))
    throw InputError(InputLocation{path}, "dataset folder does not exist");
  if (fs::is_directory(path / "mav0" / "cam0")) return path / "mav0";
  if (fs::is_directory(path / "cam0")) return path;
  throw InputError(InputLocation{path},
                   "not a EuRoC sequence: found neither mav0/cam0/ nor cam0/ in this folder");
}

fs::path requireFile(const fs::path& file) {
  if (!fs::is_regular_file(file)) throw InputError(InputLocation{file}, "file does not exist");
  return file;
}

CameraList readCameraList(const fs::path& camera_dir, std::vector<std::string>& warnings) {
  CameraList list;
  list.csv = requireFile(camera_dir / "data.csv");
  forEachTextRow(list.csv, Delimiter::kComma, [&](const TextRow& row) {
    requireFieldCount(row, list.csv, 2, 2);
    const TimeNs t_ns = parseIntegerNs(row.fields[0], row.at(list.csv, "timestamp"));
    if (row.fields[1].empty()) throw InputError(row.at(list.csv, "filename"), "empty file name");
    list.images.push_back({{t_ns, camera_dir / "data" / row.fields[1]}, row.line});
    return true;
  });
  if (list.images.empty()) throw InputError(InputLocation{list.csv}, "no image rows found");
  list.images = inTimeOrder(
      std::move(list.images), [](const ListedImage& image) { return image.ref.t_ns; }, list.csv,
      warnings);
  return list;
}

/// Frames missing from a camera's list: time steps longer than 1.5 nominal periods (rate_hz of
/// its sensor.yaml), each counted as round(step / period) - 1 dropped frames.
void warnAboutDroppedFrames(const CameraList& list, double rate_hz,
                            std::vector<std::string>& warnings) {
  if (!(rate_hz > 0.0)) return;
  const double period_ns = 1e9 / rate_hz;
  long long dropped = 0;
  int steps = 0;
  ImuGaps longest;  // the same bookkeeping: count and largest step with its line
  for (std::size_t k = 1; k < list.images.size(); ++k) {
    const TimeNs step = list.images[k].ref.t_ns - list.images[k - 1].ref.t_ns;
    if (static_cast<double>(step) <= 1.5 * period_ns) continue;
    ++steps;
    dropped += std::llround(static_cast<double>(step) / period_ns) - 1;
    longest.note(step, 0, list.images[k].line);
  }
  if (steps == 0) return;
  warnings.push_back(fmt::format(
      "{}: about {} dropped frame(s) in {} time step(s) longer than 1.5 frame periods of {} Hz; "
      "the largest, {:.1f} ms, ends at line {}",
      list.csv.string(), dropped, steps, rate_hz, static_cast<double>(longest.largest_ns) / 1e6,
      longest.largest_line));
}

/// The lookup does not throw: a path the system cannot look up (a name over its length limit:
/// fuzz/corpus/euroc_csv/crash_name_too_long) is an InputError like a missing image.
void requireImageExists(const ListedImage& image, const fs::path& csv) {
  std::error_code error;
  if (fs::is_regular_file(image.ref.path, error)) return;
  const bool lookup_failed =
      error && error != std::errc::no_such_file_or_directory && error != std::errc::not_a_directory;
  throw InputError(InputLocation{csv, image.line, "filename"},
                   lookup_failed ? fmt::format("image {} cannot be looked up: {}",
                                               image.ref.path.string(), error.message())
                                 : fmt::format("image {} does not exist", image.ref.path.string()));
}

/// Merges the two time-sorted lists, pairing equal timestamps.
StereoMatch matchByTimestamp(const CameraList& cam0, const CameraList& cam1) {
  StereoMatch match;
  auto left = cam0.images.begin();
  auto right = cam1.images.begin();
  while (left != cam0.images.end() || right != cam1.images.end()) {
    if (right == cam1.images.end() ||
        (left != cam0.images.end() && left->ref.t_ns < right->ref.t_ns)) {
      match.cam0_only.push_back(&*left++);
    } else if (left == cam0.images.end() || right->ref.t_ns < left->ref.t_ns) {
      match.cam1_only.push_back(&*right++);
    } else {
      match.pairs.emplace_back(&*left++, &*right++);
    }
  }
  return match;
}

/// "cam1/data.csv: 4 frames have no cam0 frame ..." for the unpaired frames of one camera.
/// Unpaired cam1 images are never served, so a missing image among them is only mentioned.
std::string unpairedWarning(const std::vector<const ListedImage*>& unpaired, const fs::path& csv,
                            const char* other_camera, const char* consequence) {
  const auto missing = std::count_if(unpaired.begin(), unpaired.end(), [](const ListedImage* i) {
    std::error_code error;  // a path that cannot be looked up counts as missing
    return !fs::is_regular_file(i->ref.path, error);
  });
  return fmt::format(
      "{}: {} frame(s) have no {} frame with the same timestamp (first at line {}, t_ns {}); {}{}",
      csv.string(), unpaired.size(), other_camera, unpaired.front()->line,
      unpaired.front()->ref.t_ns, consequence,
      missing > 0 ? fmt::format(" ({} of their images do not exist)", missing) : "");
}

/// Every cam0 image is served by monoFrames(), so each one must exist.
std::vector<ImageRef> servedFrames(const CameraList& cam0) {
  std::vector<ImageRef> frames;
  for (const ListedImage& image : cam0.images) {
    requireImageExists(image, cam0.csv);
    frames.push_back(image.ref);
  }
  return frames;
}

/// The stereo pairs (their cam1 images must exist); unpaired frames of either camera are reported.
std::vector<StereoFrameRef> pairStereoFrames(const CameraList& cam0, const CameraList& cam1,
                                             std::vector<std::string>& warnings) {
  const StereoMatch match = matchByTimestamp(cam0, cam1);
  std::vector<StereoFrameRef> frames;
  for (const auto& [left, right] : match.pairs) {
    requireImageExists(*right, cam1.csv);
    frames.push_back({left->ref.t_ns, left->ref.path, right->ref.path});
  }
  if (!match.cam0_only.empty()) {
    warnings.push_back(
        unpairedWarning(match.cam0_only, cam0.csv, "cam1", "they are in monoFrames() only"));
  }
  if (!match.cam1_only.empty()) {
    warnings.push_back(unpairedWarning(match.cam1_only, cam1.csv, "cam0", "they are not used"));
  }
  return frames;
}

/// The value of an IMU field; nullopt for a non-finite number ("nan", "inf": a sensor glitch the
/// driver passed through); InputError for anything that is not a number.
std::optional<double> parseImuValue(std::string_view field, const InputLocation& where) {
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (!field.empty() && ec == std::errc() && ptr == field.data() + field.size() &&
      !std::isfinite(value)) {
    return std::nullopt;
  }
  return parseFiniteDouble(field, where);
}

/// "5, 7-9, 12": the line numbers (ascending) with runs of consecutive ones joined, at most
/// `max_runs` runs and then "...".
std::string lineRuns(const std::vector<int>& lines, std::size_t max_runs) {
  std::string text;
  std::size_t runs = 0;
  for (std::size_t i = 0; i < lines.size(); ++runs) {
    std::size_t j = i;
    while (j + 1 < lines.size() && lines[j + 1] == lines[j] + 1)
      ++j;
    if (runs > 0) text += ", ";
    if (runs == max_runs) {
      text += "...";
      break;
    }
    text += j == i ? fmt::format("{}", lines[i]) : fmt::format("{}-{}", lines[i], lines[j]);
    i = j + 1;
  }
  return text;
}

/// An IMU row with its line, for the reports.
struct ImuRow {
  sensors::ImuSample sample;
  int line = 0;
};

/// Whether a sample is at or beyond the sensor's range on some axis (a clipped reading); ranges
/// <= 0 are unknown and never match.
bool saturated(const sensors::ImuSample& sample, const sensors::ImuCalibration& calibration) {
  const auto beyond = [](const Eigen::Vector3d& v, double range) {
    return range > 0.0 && v.cwiseAbs().maxCoeff() >= range;
  };
  return beyond(sample.gyro, calibration.gyroscope_range) ||
         beyond(sample.accel, calibration.accelerometer_range);
}

std::vector<sensors::ImuSample> readImuCsv(const fs::path& csv,
                                           const sensors::ImuCalibration& calibration,
                                           std::vector<std::string>& warnings) {
  static constexpr std::array<const char*, 6> kNames = {"gyro_x",  "gyro_y",  "gyro_z",
                                                        "accel_x", "accel_y", "accel_z"};
  const auto gap_threshold_ns =
      static_cast<TimeNs>(kImuGapWarningPeriods * static_cast<double>(calibration.periodNs()));
  std::vector<ImuRow> rows;
  std::vector<int> non_finite_lines, saturated_lines;
  forEachTextRow(csv, Delimiter::kComma, [&](const TextRow& row) {
    requireFieldCount(row, csv, 7, 7);
    sensors::ImuSample sample;
    sample.t_ns = parseIntegerNs(row.fields[0], row.at(csv, "timestamp"));
    bool finite = true;
    for (std::size_t i = 0; i < kNames.size(); ++i) {
      const std::optional<double> value = parseImuValue(row.fields[i + 1], row.at(csv, kNames[i]));
      finite = finite && value.has_value();
      (i < 3 ? sample.gyro : sample.accel)[static_cast<Eigen::Index>(i % 3)] = value.value_or(0.0);
    }
    if (!finite) {
      non_finite_lines.push_back(row.line);
    } else if (saturated(sample, calibration)) {
      saturated_lines.push_back(row.line);
    } else {
      rows.push_back({sample, row.line});
    }
    return true;
  });
  if (!non_finite_lines.empty()) {
    warnings.push_back(fmt::format("{}: {} row(s) with nan or inf values skipped (lines {})",
                                   csv.string(), non_finite_lines.size(),
                                   lineRuns(non_finite_lines, 5)));
  }
  if (!saturated_lines.empty()) {
    warnings.push_back(fmt::format(
        "{}: {} row(s) at the sensor's range (saturated: |gyro| >= {} rad/s or |accel| >= {} "
        "m/s^2, sensor.yaml) skipped (lines {})",
        csv.string(), saturated_lines.size(), calibration.gyroscope_range,
        calibration.accelerometer_range, lineRuns(saturated_lines, 5)));
  }
  if (rows.empty()) throw InputError(InputLocation{csv}, "no IMU rows found");
  rows = inTimeOrder(
      std::move(rows), [](const ImuRow& row) { return row.sample.t_ns; }, csv, warnings);
  std::vector<sensors::ImuSample> samples;
  samples.reserve(rows.size());
  ImuGaps gaps;
  for (const ImuRow& row : rows) {
    if (!samples.empty())
      gaps.note(row.sample.t_ns - samples.back().t_ns, gap_threshold_ns, row.line);
    samples.push_back(row.sample);
  }
  if (gaps.count > 0) {
    warnings.push_back(fmt::format(
        "{}: {} gap(s) longer than {} nominal periods ({:.1f} ms); the largest, {:.1f} ms, ends at "
        "line {}",
        csv.string(), gaps.count, kImuGapWarningPeriods,
        static_cast<double>(gap_threshold_ns) / 1e6, static_cast<double>(gaps.largest_ns) / 1e6,
        gaps.largest_line));
  }
  return samples;
}

Eigen::Vector3d parseVector3(const TextRow& row, const fs::path& csv, std::size_t first,
                             const std::array<const char*, 3>& names) {
  Eigen::Vector3d v;
  for (std::size_t i = 0; i < 3; ++i) {
    v[static_cast<Eigen::Index>(i)] =
        parseFiniteDouble(row.fields[first + i], row.at(csv, names[i]));
  }
  return v;
}

sensors::GroundTruthState parseGroundTruthRow(const TextRow& row, const fs::path& csv,
                                              bool full_state) {
  sensors::GroundTruthState state;
  state.t_ns = parseIntegerNs(row.fields[0], row.at(csv, "timestamp"));
  const Eigen::Vector3d p = parseVector3(row, csv, 1, {"p_x", "p_y", "p_z"});
  const double qw = parseFiniteDouble(row.fields[4], row.at(csv, "q_w"));
  const Eigen::Vector3d q_xyz = parseVector3(row, csv, 5, {"q_x", "q_y", "q_z"});
  const Eigen::Quaterniond q =
      checkedQuaternion(qw, q_xyz.x(), q_xyz.y(), q_xyz.z(), row.at(csv, "quaternion"));
  state.T_w_b = SE3d(q, p);
  if (full_state) {
    state.v_w = parseVector3(row, csv, 8, {"v_x", "v_y", "v_z"});
    state.bg = parseVector3(row, csv, 11, {"bg_x", "bg_y", "bg_z"});
    state.ba = parseVector3(row, csv, 14, {"ba_x", "ba_y", "ba_z"});
  }
  return state;
}

/// Ground truth: t, p(3), q_wxyz(4)[, v(3), b_w(3), b_a(3)]. The first row decides whether the
/// file carries the full state (>= 17 columns) or only poses (8..16); every row must then have as
/// many columns as the first, so a truncated row is an error rather than a silent pose-only row.
GroundTruthRows readGroundTruthCsv(const fs::path& csv) {
  GroundTruthRows result;
  std::size_t columns = 0;
  forEachTextRow(csv, Delimiter::kComma, [&](const TextRow& row) {
    if (columns == 0) {
      requireFieldCount(row, csv, 8);
      columns = row.fields.size();
      result.full_state = columns >= 17;
    }
    requireFieldCount(row, csv, columns, columns);
    result.states.push_back(parseGroundTruthRow(row, csv, result.full_state));
    if (result.states.size() > 1) {
      requireIncreasingTime(result.states[result.states.size() - 2].t_ns, result.states.back().t_ns,
                            true, row.at(csv, "timestamp"));
    }
    return true;
  });
  if (result.states.empty()) throw InputError(InputLocation{csv}, "no ground-truth rows found");
  return result;
}

/// The class id of a class name; nullopt for "unlabelled" (agents the masks do not hold).
std::optional<int> instanceClassId(const std::string& name, const InputLocation& where) {
  if (name == "unlabelled") return std::nullopt;
  for (const int id : {sensors::kInstanceClassBackground, sensors::kInstanceClassVehicle,
                       sensors::kInstanceClassPedestrian, sensors::kInstanceClassOtherMovable}) {
    if (name == sensors::instanceClassName(id)) return id;
  }
  throw InputError(where, fmt::format("unknown class '{}' (background | vehicle | pedestrian | "
                                      "other_movable | unlabelled)",
                                      name));
}

template <typename T>
std::optional<TimeRange> rangeOf(const std::vector<T>& samples) {
  if (samples.empty()) return std::nullopt;
  return TimeRange{samples.front().t_ns, samples.back().t_ns};
}

}  // namespace

std::map<int, int> readInstanceClasses(const fs::path& csv) {
  std::map<int, int> classes;
  std::set<int> ids;
  for (const TextRow& row : readTextRows(csv, Delimiter::kComma)) {
    requireFieldCount(row, csv, 2);
    const double id = parseFiniteDouble(row.fields[0], row.at(csv, "id"));
    if (id != std::round(id) || id < 1 || id > 65535) {
      throw InputError(row.at(csv, "id"), "expected an instance id in [1, 65535]");
    }
    if (!ids.insert(static_cast<int>(id)).second) {
      throw InputError(row.at(csv, "id"), fmt::format("instance {} listed twice", id));
    }
    const auto class_id = instanceClassId(row.fields[1], row.at(csv, "class"));
    if (class_id) classes.emplace(static_cast<int>(id), *class_id);
  }
  return classes;
}

EurocDataset EurocDataset::open(const fs::path& path) {
  EurocDataset dataset;
  dataset.root_ = findMav0(path);
  const fs::path cam0_dir = dataset.root_ / "cam0";
  dataset.cam0_ = readCameraCalibration(cam0_dir / "sensor.yaml");
  const CameraList cam0 = readCameraList(cam0_dir, dataset.warnings_);
  dataset.cam0_frames_ = servedFrames(cam0);
  warnAboutDroppedFrames(cam0, dataset.cam0_.rate_hz, dataset.warnings_);

  const fs::path cam1_dir = dataset.root_ / "cam1";
  if (fs::is_directory(cam1_dir)) {
    dataset.cam1_ = readCameraCalibration(cam1_dir / "sensor.yaml");
    const CameraList cam1 = readCameraList(cam1_dir, dataset.warnings_);
    dataset.cam1_range_ = TimeRange{cam1.images.front().ref.t_ns, cam1.images.back().ref.t_ns};
    dataset.stereo_frames_ = pairStereoFrames(cam0, cam1, dataset.warnings_);
  }

  const fs::path imu_dir = dataset.root_ / "imu0";
  if (fs::is_directory(imu_dir)) {
    dataset.imu_calibration_ = readImuCalibration(imu_dir / "sensor.yaml");
    dataset.imu_ =
        readImuCsv(requireFile(imu_dir / "data.csv"), *dataset.imu_calibration_, dataset.warnings_);
  }

  const fs::path ground_truth_csv = dataset.root_ / "state_groundtruth_estimate0" / "data.csv";
  if (fs::is_regular_file(ground_truth_csv)) {
    GroundTruthRows rows = readGroundTruthCsv(ground_truth_csv);
    dataset.ground_truth_ = std::move(rows.states);
    dataset.ground_truth_full_state_ = rows.full_state;
  }

  const fs::path instances_csv = dataset.root_ / "instances.csv";
  if (fs::is_regular_file(instances_csv) && fs::is_directory(cam0_dir / "mask")) {
    dataset.instance_classes_ = readInstanceClasses(instances_csv);
    dataset.has_instance_masks_ = true;
  }
  return dataset;
}

cv::Mat EurocDataset::loadInstanceMask(const fs::path& image, cv::Size size) const {
  const fs::path file = image.parent_path().parent_path() / "mask" / image.filename();
  if (!fs::is_regular_file(file)) throw InputError(InputLocation{file}, "mask file does not exist");
  const cv::Mat mask = decodePngFile(file, cv::IMREAD_UNCHANGED);
  if (mask.type() != CV_16UC1 || mask.size() != size) {
    throw InputError(InputLocation{file},
                     fmt::format("expected a 16-bit single-channel {}x{} mask, got {}x{} of "
                                 "OpenCV type {}",
                                 size.width, size.height, mask.cols, mask.rows, mask.type()));
  }
  for (int r = 0; r < mask.rows; ++r) {
    const auto* row = mask.ptr<std::uint16_t>(r);
    for (int c = 0; c < mask.cols; ++c) {
      if (row[c] != 0 && !instance_classes_.contains(row[c])) {
        throw InputError(
            InputLocation{file},
            fmt::format("pixel ({}, {}) holds instance {}, which {} does not list with a "
                        "labelled class",
                        c, r, row[c], (root_ / "instances.csv").string()));
      }
    }
  }
  return mask;
}

TimeRange EurocDataset::cam0TimeRange() const {
  return *rangeOf(cam0_frames_);
}

std::optional<TimeRange> EurocDataset::cam1TimeRange() const {
  return cam1_range_;
}

std::optional<TimeRange> EurocDataset::imuTimeRange() const {
  return rangeOf(imu_);
}

std::optional<TimeRange> EurocDataset::groundTruthTimeRange() const {
  return rangeOf(ground_truth_);
}

std::span<const sensors::ImuSample> EurocDataset::imuBetween(TimeNs t0_ns, TimeNs t1_ns) const {
  if (t1_ns < t0_ns) return {};
  const auto by_time = [](const sensors::ImuSample& s, TimeNs t) { return s.t_ns < t; };
  const auto first = std::lower_bound(imu_.begin(), imu_.end(), t0_ns, by_time);
  const auto last = std::upper_bound(
      first, imu_.end(), t1_ns, [](TimeNs t, const sensors::ImuSample& s) { return t < s.t_ns; });
  return {first, last};
}

bool EurocDataset::hasImuCoverage(TimeNs t_ns) const {
  return !imu_.empty() && imu_.front().t_ns <= t_ns && t_ns <= imu_.back().t_ns;
}

std::vector<StereoFrameRef> EurocDataset::framesWithImuCoverage() const {
  std::vector<StereoFrameRef> covered;
  std::copy_if(stereo_frames_.begin(), stereo_frames_.end(), std::back_inserter(covered),
               [this](const StereoFrameRef& f) { return hasImuCoverage(f.t_ns); });
  return covered;
}

std::vector<ImageRef> EurocDataset::monoFramesWithImuCoverage() const {
  std::vector<ImageRef> covered;
  std::copy_if(cam0_frames_.begin(), cam0_frames_.end(), std::back_inserter(covered),
               [this](const ImageRef& f) { return hasImuCoverage(f.t_ns); });
  return covered;
}

Trajectory EurocDataset::groundTruthTrajectory() const {
  Trajectory trajectory;
  trajectory.reserve(ground_truth_.size());
  for (const sensors::GroundTruthState& state : ground_truth_)
    trajectory.push_back({state.t_ns, state.T_w_b});
  return trajectory;
}

std::optional<sensors::GroundTruthState> EurocDataset::groundTruthNearest(
    TimeNs t_ns, TimeNs max_diff_ns) const {
  if (ground_truth_.empty()) return std::nullopt;
  auto nearest =
      std::lower_bound(ground_truth_.begin(), ground_truth_.end(), t_ns,
                       [](const sensors::GroundTruthState& s, TimeNs t) { return s.t_ns < t; });
  // The nearest state is the first at or after t_ns, or the one just before it.
  if (nearest == ground_truth_.end() || (nearest != ground_truth_.begin() &&
                                         t_ns - std::prev(nearest)->t_ns < nearest->t_ns - t_ns)) {
    nearest = std::prev(nearest);
  }
  if (std::abs(nearest->t_ns - t_ns) > max_diff_ns) return std::nullopt;
  return *nearest;
}

}  // namespace superdyna::io
