#include "superdyna/io/trajectory_io.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <array>
#include <charconv>
#include <cmath>
#include <fstream>
#include <optional>

#include "superdyna/core/atomic_file.h"
#include "superdyna/core/error.h"
#include "superdyna/io/text_table.h"

namespace superdyna::io {

namespace fs = std::filesystem;

namespace {

constexpr TimeNs kKittiDefaultPeriodNs = 100 * kNsPerMillisecond;

bool startsWithNumber(const TextRow& row) {
  const std::string_view text = row.text;
  const char* begin = text.data() + (!text.empty() && text.front() == '+' ? 1 : 0);
  const char* end = text.data() + text.size();
  double value = 0.0;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  return ec == std::errc() && (ptr == end || *ptr == ',' || *ptr == ' ' || *ptr == '\t');
}

void requireIncreasing(const Trajectory& trajectory, const TextRow& row, const fs::path& file) {
  if (trajectory.size() < 2) return;
  requireIncreasingTime(trajectory[trajectory.size() - 2].t_ns, trajectory.back().t_ns, true,
                        row.at(file, "timestamp"));
}

std::array<double, 7> parseNumbers(const TextRow& row, const fs::path& file, std::size_t first,
                                   const std::array<const char*, 7>& names) {
  std::array<double, 7> values{};
  for (std::size_t i = 0; i < values.size(); ++i) {
    values[i] = parseFiniteDouble(row.fields[first + i], row.at(file, names[i]));
  }
  return values;
}

/// "key: value" metadata lines of OpenLORIS-style files ("scene: market", "seq: 2").
bool isMetadataLine(const TextRow& row) {
  return !row.fields.empty() && row.fields.front().size() > 1 && row.fields.front().back() == ':' &&
         !startsWithNumber(row);
}

/// Segment numbers are whole numbers that fit an int (OpenLORIS numbers them 1, 2, ...).
constexpr double kMaxSegmentNumber = 1e9;

std::optional<int> segmentNumber(const TextRow& row, const fs::path& file) {
  if (row.fields.front() != "seq:") return std::nullopt;
  requireFieldCount(row, file, 2, 2);
  const double number = parseFiniteDouble(row.fields[1], row.at(file, "seq"));
  if (number != std::round(number) || std::abs(number) > kMaxSegmentNumber) {
    throw InputError(row.at(file, "seq"),
                     fmt::format("'{}' is not a segment number (a whole number up to {:g})",
                                 row.fields[1], kMaxSegmentNumber));
  }
  return static_cast<int>(number);
}

/// A TUM time column written in nanoseconds, possibly with a fraction ("1403636579763555584.0").
TimeNs parseNanosecondsField(std::string_view field, const InputLocation& where) {
  const double ns = parseFiniteDouble(field, where);
  // 9.2e18 ns is int64's limit (year 2262); a time in seconds given by mistake stays far below
  // 1e12.
  if (ns < 0.0 || ns > 9.2e18) {
    throw InputError(where, fmt::format("'{}' is not a time in nanoseconds", field));
  }
  return static_cast<TimeNs>(std::llround(ns));
}

Trajectory readTum(const fs::path& file, std::optional<int> wanted_segment, bool time_in_ns) {
  Trajectory trajectory;
  std::optional<int> segment;
  std::vector<int> segments_seen;
  forEachTextRow(file, Delimiter::kWhitespace, [&](const TextRow& row) {
    if (isMetadataLine(row)) {
      if (auto n = segmentNumber(row, file)) {
        segment = n;
        segments_seen.push_back(*n);
      }
      return true;
    }
    if (trajectory.empty() && !startsWithNumber(row)) return true;  // column-name header line
    if (wanted_segment && segment != wanted_segment) return true;
    requireFieldCount(row, file, 8, 8);
    const TimeNs t_ns = time_in_ns ? parseNanosecondsField(row.fields[0], row.at(file, "timestamp"))
                                   : parseSecondsField(row.fields[0], row.at(file, "timestamp"));
    const auto v = parseNumbers(row, file, 1, {"tx", "ty", "tz", "qx", "qy", "qz", "qw"});
    const auto q = checkedQuaternion(v[6], v[3], v[4], v[5], row.at(file, "quaternion"));
    trajectory.push_back({t_ns, SE3d(q, Eigen::Vector3d(v[0], v[1], v[2]))});
    requireIncreasing(trajectory, row, file);
    return true;
  });
  if (wanted_segment && trajectory.empty()) {
    throw InputError(InputLocation(file, 0, "seq"),
                     fmt::format("no rows in segment 'seq: {}' (segments found: {})",
                                 *wanted_segment, fmt::join(segments_seen, ", ")));
  }
  return trajectory;
}

Trajectory readEuroc(const fs::path& file) {
  Trajectory trajectory;
  forEachTextRow(file, Delimiter::kComma, [&](const TextRow& row) {
    // Header lines ("timestamp,x,..") precede the first numeric row; after it every row is data.
    if (trajectory.empty() && !startsWithNumber(row)) return true;
    requireFieldCount(row, file, 8);
    const TimeNs t_ns = parseIntegerNs(row.fields[0], row.at(file, "timestamp"));
    const auto v = parseNumbers(row, file, 1, {"p_x", "p_y", "p_z", "q_w", "q_x", "q_y", "q_z"});
    const auto q = checkedQuaternion(v[3], v[4], v[5], v[6], row.at(file, "quaternion"));
    trajectory.push_back({t_ns, SE3d(q, Eigen::Vector3d(v[0], v[1], v[2]))});
    requireIncreasing(trajectory, row, file);
    return true;
  });
  return trajectory;
}

SE3d parseKittiPose(const TextRow& row, const fs::path& file) {
  const Eigen::Matrix<double, 3, 4> M = parseRowMajor3x4(row, file);
  requireRotationMatrix(M.leftCols<3>(), row.at(file, "rotation"));
  return SE3d::fromMatrix(M);
}

Trajectory readKitti(const fs::path& file, const std::optional<fs::path>& times_file) {
  const std::vector<TimeNs> times = times_file ? readTimesFile(*times_file) : std::vector<TimeNs>{};
  Trajectory trajectory;
  forEachTextRow(file, Delimiter::kWhitespace, [&](const TextRow& row) {
    requireFieldCount(row, file, 12, 12);
    const std::size_t index = trajectory.size();
    if (times_file && index >= times.size()) {
      throw InputError(row.at(file), fmt::format("more poses than the {} timestamps in {}",
                                                 times.size(), times_file->string()));
    }
    const TimeNs t_ns =
        times_file ? times[index] : static_cast<TimeNs>(index) * kKittiDefaultPeriodNs;
    trajectory.push_back({t_ns, parseKittiPose(row, file)});
    return true;
  });
  return trajectory;
}

void writeLines(const fs::path& file, const Trajectory& trajectory, const std::string& header,
                const auto& format_pose) {
  AtomicFile atomic(file);  // a crash never leaves a half-written trajectory
  std::ofstream& out = atomic.stream();
  out << header;
  for (const StampedPose& pose : trajectory)
    out << format_pose(pose) << '\n';
  atomic.commit();
}

}  // namespace

TrajectoryFormat parseTrajectoryFormat(const std::string& name) {
  if (name == "auto") return TrajectoryFormat::kAuto;
  if (name == "tum") return TrajectoryFormat::kTum;
  if (name == "euroc") return TrajectoryFormat::kEuroc;
  if (name == "kitti") return TrajectoryFormat::kKitti;
  throw OptionError("format",
                    fmt::format("unknown trajectory format '{}' (auto|tum|euroc|kitti)", name));
}

std::string toString(TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kAuto:
      return "auto";
    case TrajectoryFormat::kTum:
      return "tum";
    case TrajectoryFormat::kEuroc:
      return "euroc";
    case TrajectoryFormat::kKitti:
      return "kitti";
  }
  return "unknown";
}

TrajectoryFormat detectTrajectoryFormat(const fs::path& file) {
  std::optional<TextRow> first_row;  // the first row that starts with a number
  forEachTextRow(file, Delimiter::kWhitespace, [&first_row](const TextRow& row) {
    if (startsWithNumber(row)) first_row = row;
    return !first_row;
  });
  if (!first_row) throw InputError(InputLocation{file}, "no trajectory rows found");
  const TextRow& first = *first_row;
  if (first.text.find(',') != std::string::npos) return TrajectoryFormat::kEuroc;
  if (first.fields.size() == 12) return TrajectoryFormat::kKitti;
  if (first.fields.size() == 8) return TrajectoryFormat::kTum;
  throw InputError(first.at(file),
                   fmt::format("cannot detect the trajectory format from a row of {} fields "
                               "(TUM has 8, KITTI 12, EuRoC is comma-separated); state it "
                               "with a format option",
                               first.fields.size()));
}

Trajectory readTrajectory(const fs::path& file, const TrajectoryReadOptions& options) {
  if (!fs::exists(file)) throw InputError(InputLocation{file}, "file does not exist");
  const TrajectoryFormat format =
      options.format == TrajectoryFormat::kAuto ? detectTrajectoryFormat(file) : options.format;
  if (options.tum_time_in_ns && format != TrajectoryFormat::kTum) {
    throw OptionError("time unit", "nanosecond time columns are read only from TUM-format files");
  }
  Trajectory trajectory;
  switch (format) {
    case TrajectoryFormat::kTum:
      trajectory = readTum(file, options.segment, options.tum_time_in_ns);
      break;
    case TrajectoryFormat::kEuroc:
      trajectory = readEuroc(file);
      break;
    case TrajectoryFormat::kKitti:
    case TrajectoryFormat::kAuto:
      trajectory = readKitti(file, options.kitti_times);
      break;
  }
  if (trajectory.empty()) throw InputError(InputLocation{file}, "no trajectory rows found");
  if (options.segment && format != TrajectoryFormat::kTum) {
    throw OptionError("segment", "segments ('seq: N' blocks) exist only in TUM-format files");
  }
  return trajectory;
}

Trajectory readTrajectory(const fs::path& file) {
  return readTrajectory(file, {});
}

std::vector<TimeNs> readTimesFile(const fs::path& file) {
  std::vector<TimeNs> times;
  forEachTextRow(file, Delimiter::kWhitespace, [&](const TextRow& row) {
    requireFieldCount(row, file, 1, 1);
    const TimeNs t_ns = parseSecondsField(row.fields[0], row.at(file, "time"));
    requireIncreasingTime(times.empty() ? 0 : times.back(), t_ns, !times.empty(),
                          row.at(file, "time"));
    times.push_back(t_ns);
    return true;
  });
  if (times.empty()) throw InputError(InputLocation{file}, "no timestamps found");
  return times;
}

void writeTrajectory(const fs::path& file, const Trajectory& trajectory, TrajectoryFormat format) {
  switch (format) {
    case TrajectoryFormat::kTum:
      writeLines(file, trajectory, "# timestamp(s) tx ty tz qx qy qz qw\n",
                 [](const StampedPose& p) {
                   const auto& q = p.T_w_x.q;
                   const auto& t = p.T_w_x.t;
                   return fmt::format("{} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f} {:.9f}",
                                      formatNsAsSeconds(p.t_ns), t.x(), t.y(), t.z(), q.x(), q.y(),
                                      q.z(), q.w());
                 });
      return;
    case TrajectoryFormat::kEuroc:
      writeLines(file, trajectory,
                 "#timestamp [ns],p_RS_R_x [m],p_RS_R_y [m],p_RS_R_z [m],q_RS_w [],q_RS_x [],"
                 "q_RS_y [],q_RS_z []\n",
                 [](const StampedPose& p) {
                   const auto& q = p.T_w_x.q;
                   const auto& t = p.T_w_x.t;
                   return fmt::format("{},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f},{:.9f}", p.t_ns,
                                      t.x(), t.y(), t.z(), q.w(), q.x(), q.y(), q.z());
                 });
      return;
    case TrajectoryFormat::kKitti:
      writeLines(file, trajectory, "", [](const StampedPose& p) {
        const Eigen::Matrix<double, 3, 4> M = p.T_w_x.matrix3x4();
        std::string line;
        for (int i = 0; i < 12; ++i) {
          line += fmt::format("{}{:.9e}", i == 0 ? "" : " ", M(i / 4, i % 4));
        }
        return line;
      });
      return;
    case TrajectoryFormat::kAuto:
      break;
  }
  throw OptionError("format", "an output trajectory format must be tum, euroc or kitti");
}

}  // namespace superdyna::io
