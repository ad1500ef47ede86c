#pragma once
// Line-oriented reading of delimited text files (CSV, whitespace-separated) with line numbers, so
// every parse error can name the file, the line and the field.

#include <Eigen/Core>
#include <Eigen/Geometry>
#include <filesystem>
#include <functional>
#include <string>
#include <string_view>
#include <vector>

#include "superdyna/core/error.h"
#include "superdyna/core/time.h"

namespace superdyna::io {

enum class Delimiter { kComma, kWhitespace };

/// One non-empty, non-comment line split into fields.
struct TextRow {
  int line = 0;                     ///< 1-based line number in the file.
  std::string text;                 ///< The line without its line ending and outer blanks.
  std::vector<std::string> fields;  ///< Owned copies: rows can be moved and erased freely.

  InputLocation at(const std::filesystem::path& file, std::string_view field = {}) const {
    return InputLocation{file, line, std::string(field)};
  }
};

/// Reads every line of `file`; drops empty lines and lines starting with '#' (after leading
/// blanks). Throws InputError when the file cannot be opened.
std::vector<TextRow> readTextRows(const std::filesystem::path& file, Delimiter delimiter);

/// The rows readTextRows would return, one at a time and in order, without holding the file in
/// memory (the IMU and ground truth of a 31.5-minute EuRoC-layout sequence, 378 000 rows each,
/// took 685 MB at the peak as TextRows, and the heap kept most of it). `visit` returns whether to
/// read on; the row it gets is reused for the next line, so it copies what it keeps. Throws
/// InputError when the file cannot be opened.
void forEachTextRow(const std::filesystem::path& file, Delimiter delimiter,
                    const std::function<bool(const TextRow&)>& visit);

/// Splits one line. Comma fields are trimmed of surrounding blanks; "a,,b" gives an empty field.
std::vector<std::string_view> splitFields(std::string_view line, Delimiter delimiter);

/// Strict parsers: the whole field must be a number. Throw InputError naming `where`.
double parseFiniteDouble(std::string_view field, const InputLocation& where);
TimeNs parseIntegerNs(std::string_view field, const InputLocation& where);
TimeNs parseSecondsField(std::string_view field, const InputLocation& where);

/// Throws unless `row` has at least `min_fields` (and, if max_fields > 0, at most max_fields).
void requireFieldCount(const TextRow& row, const std::filesystem::path& file,
                       std::size_t min_fields, std::size_t max_fields = 0);

/// Throws unless t_ns is strictly greater than the previous timestamp of the same stream.
void requireIncreasingTime(TimeNs previous_ns, TimeNs t_ns, bool has_previous,
                           const InputLocation& where);

/// Parses 12 fields starting at `first` as a row-major 3x4 matrix (KITTI poses and projection
/// matrices); fields are named "m00".."m23" in errors. The row must hold first + 12 fields.
Eigen::Matrix<double, 3, 4> parseRowMajor3x4(const TextRow& row, const std::filesystem::path& file,
                                             std::size_t first = 0);

/// Validation of parsed rotations, shared by every reader so that all apply the same tolerances.
inline constexpr double kQuaternionNormTolerance = 1e-2;
inline constexpr double kRotationOrthonormalityTolerance = 1e-3;

/// The quaternion (w, x, y, z), normalised; throws unless its norm is within
/// kQuaternionNormTolerance of 1 (a larger error means a wrong column, not rounding).
Eigen::Quaterniond checkedQuaternion(double w, double x, double y, double z,
                                     const InputLocation& where);

/// Throws unless R is a proper rotation: |R^T R - I| <= kRotationOrthonormalityTolerance in
/// every element and det(R) > 0. Callers then re-orthonormalise (SE3d::fromMatrix).
void requireRotationMatrix(const Eigen::Matrix3d& R, const InputLocation& where);

}  // namespace superdyna::io
