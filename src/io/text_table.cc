#include "superdyna/io/text_table.h"

#include <fmt/format.h>

#include <charconv>
#include <cmath>
#include <fstream>

namespace superdyna::io {

namespace {

std::string_view trim(std::string_view s) {
  const auto first = s.find_first_not_of(" \t\r");
  if (first == std::string_view::npos) return {};
  const auto last = s.find_last_not_of(" \t\r");
  return s.substr(first, last - first + 1);
}

}  // namespace

std::vector<std::string_view> splitFields(std::string_view line, Delimiter delimiter) {
  std::vector<std::string_view> fields;
  if (delimiter == Delimiter::kComma) {
    std::size_t start = 0;
    while (true) {
      const std::size_t comma = line.find(',', start);
      fields.push_back(trim(line.substr(start, comma - start)));
      if (comma == std::string_view::npos) break;
      start = comma + 1;
    }
    return fields;
  }
  std::size_t pos = 0;
  while (pos < line.size()) {
    pos = line.find_first_not_of(" \t\r", pos);
    if (pos == std::string_view::npos) break;
    const std::size_t end = line.find_first_of(" \t\r", pos);
    fields.push_back(line.substr(pos, end - pos));
    pos = end;
  }
  return fields;
}

void forEachTextRow(const std::filesystem::path& file, Delimiter delimiter,
                    const std::function<bool(const TextRow&)>& visit) {
  std::ifstream in(file);
  if (!in) throw InputError(InputLocation{file}, "cannot open file");
  TextRow row;
  std::string line;
  int number = 0;
  while (std::getline(in, line)) {
    ++number;
    const std::string_view content = trim(line);
    if (content.empty() || content.front() == '#') continue;
    row.line = number;
    row.text.assign(content);
    const std::vector<std::string_view> fields = splitFields(content, delimiter);
    row.fields.resize(fields.size());  // keeps the strings' buffers from row to row
    for (std::size_t i = 0; i < fields.size(); ++i)
      row.fields[i].assign(fields[i]);
    if (!visit(row)) return;
  }
}

std::vector<TextRow> readTextRows(const std::filesystem::path& file, Delimiter delimiter) {
  std::vector<TextRow> rows;
  forEachTextRow(file, delimiter, [&rows](const TextRow& row) {
    rows.push_back(row);
    return true;
  });
  return rows;
}

double parseFiniteDouble(std::string_view field, const InputLocation& where) {
  double value = 0.0;
  const char* begin = field.data();
  const char* end = field.data() + field.size();
  if (!field.empty() && field.front() == '+') ++begin;
  const auto [ptr, ec] = std::from_chars(begin, end, value);
  if (field.empty() || ec != std::errc() || ptr != end) {
    throw InputError(where, fmt::format("'{}' is not a number", field));
  }
  if (!std::isfinite(value)) throw InputError(where, fmt::format("'{}' is not finite", field));
  return value;
}

TimeNs parseIntegerNs(std::string_view field, const InputLocation& where) {
  TimeNs value = 0;
  const auto [ptr, ec] = std::from_chars(field.data(), field.data() + field.size(), value);
  if (field.empty() || ec != std::errc() || ptr != field.data() + field.size()) {
    throw InputError(where, fmt::format("'{}' is not an integer timestamp in nanoseconds", field));
  }
  return value;
}

TimeNs parseSecondsField(std::string_view field, const InputLocation& where) {
  const auto t_ns = parseSecondsToNs(field);
  if (!t_ns) throw InputError(where, fmt::format("'{}' is not a timestamp in seconds", field));
  return *t_ns;
}

void requireFieldCount(const TextRow& row, const std::filesystem::path& file,
                       std::size_t min_fields, std::size_t max_fields) {
  const std::size_t n = row.fields.size();
  if (n < min_fields || (max_fields > 0 && n > max_fields)) {
    const std::string expected = max_fields == min_fields ? fmt::format("{}", min_fields)
                                 : max_fields == 0
                                     ? fmt::format("at least {}", min_fields)
                                     : fmt::format("{} to {}", min_fields, max_fields);
    throw InputError(
        row.at(file),
        fmt::format("expected {} fields, found {} (truncated or malformed row)", expected, n));
  }
}

void requireIncreasingTime(TimeNs previous_ns, TimeNs t_ns, bool has_previous,
                           const InputLocation& where) {
  if (!has_previous || t_ns > previous_ns) return;
  throw InputError(where, t_ns == previous_ns
                              ? fmt::format("duplicate timestamp {} ns", t_ns)
                              : fmt::format("timestamp {} ns is earlier than the previous row's {} "
                                            "ns (timestamps must increase)",
                                            t_ns, previous_ns));
}

Eigen::Matrix<double, 3, 4> parseRowMajor3x4(const TextRow& row, const std::filesystem::path& file,
                                             std::size_t first) {
  Eigen::Matrix<double, 3, 4> M;
  for (int i = 0; i < 12; ++i) {
    M(i / 4, i % 4) = parseFiniteDouble(row.fields[first + static_cast<std::size_t>(i)],
                                        row.at(file, fmt::format("m{}{}", i / 4, i % 4)));
  }
  return M;
}

Eigen::Quaterniond checkedQuaternion(double w, double x, double y, double z,
                                     const InputLocation& where) {
  Eigen::Quaterniond q(w, x, y, z);
  const double norm = q.norm();
  if (std::abs(norm - 1.0) > kQuaternionNormTolerance) {
    throw InputError(where, fmt::format("quaternion norm is {:.6f}, expected 1", norm));
  }
  q.normalize();
  return q;
}

void requireRotationMatrix(const Eigen::Matrix3d& R, const InputLocation& where) {
  const double deviation = (R.transpose() * R - Eigen::Matrix3d::Identity()).cwiseAbs().maxCoeff();
  if (deviation > kRotationOrthonormalityTolerance || R.determinant() < 0.0) {
    throw InputError(
        where, fmt::format("rotation block is not orthonormal (|R^T R - I| = {:.2e})", deviation));
  }
}

}  // namespace superdyna::io
