#pragma once
// Shrinking a gray image by area averaging, as cv::resize(src, dst, size, 0, 0, cv::INTER_AREA)
// does for factors that are not whole numbers (ORB's 1.2 pyramid), with the same result byte for
// byte and a fraction of its time.
//
// Each destination pixel is the mean of the source area it covers: per axis, the source pixels
// it overlaps weigh by their overlap (OpenCV's tables: a partial pixel under 1e-3 px is left
// out, the last pixel's cell is clipped to the image). OpenCV sums, for each destination row, the
// weighted horizontal sums of its source rows in row order, in float, and rounds to the nearest
// even. Its generic loop adds each tap to a buffer in memory one table entry at a time, and
// recomputes a source row shared by two destination rows. Here the horizontal sums keep their
// taps in registers (a fixed number per pixel, the missing ones weighing 0, which adds exactly
// 0), each source row is summed once, and the vertical sums run four pixels at a time; every
// float operation is the one OpenCV performs, in the same order, so the bytes are equal
// (AreaShrinkerTest compares them).

#include <cstdint>
#include <opencv2/core.hpp>
#include <vector>

namespace superdyna::features {

class AreaShrinker {
 public:
  /// Tables for shrinking `from` to `to`. Throws InputError unless 1 <= to <= from on both axes.
  AreaShrinker(cv::Size from, cv::Size to);

  /// Writes the shrunk CV_8UC1 `src` (of the constructor's `from` size) to `dst`. Whole-number
  /// factors on both axes are left to cv::resize (its own block-averaging path). Throws InputError
  /// for another type or size.
  void apply(const cv::Mat& src, cv::Mat& dst) const;

  cv::Size from() const { return from_; }
  cv::Size to() const { return to_; }

 private:
  /// One axis: destination pixel d averages `taps` source pixels from first[d] on, with weights
  /// weights[d * taps + t] (0 beyond the pixels it overlaps).
  struct Axis {
    std::vector<int> first;
    std::vector<float> weights;
    int taps = 0;
  };
  struct RowRing;  ///< Horizontal sums of the latest source rows.
  static Axis axisTable(int source, int destination);
  /// Sums source rows from `row` on horizontally into `ring` (four at once where four are left);
  /// returns how many. `scratch` holds 4 * (from().width + taps) floats, zero beyond the rows.
  int sumRows(const cv::Mat& src, int row, std::vector<float>& scratch, RowRing& ring) const;

  cv::Size from_, to_;
  bool whole_factors_ = false;
  Axis x_, y_;
};

}  // namespace superdyna::features
