#include "superdyna/features/area_resize.h"

#include <fmt/format.h>

#include <algorithm>
#include <cfloat>
#include <cmath>
#include <opencv2/core/hal/intrin.hpp>
#include <opencv2/imgproc.hpp>
#include <type_traits>

#include "superdyna/core/error.h"

namespace superdyna::features {

namespace {

/// A partial source pixel covered by less than this is left out [px] (OpenCV's bound).
constexpr double kMinPartial = 1e-3;

/// cv::resize's factor for an axis: the inverse of its destination / source ratio.
double areaScale(int source, int destination) {
  return 1.0 / (static_cast<double>(destination) / source);
}

bool isWholeFactor(double scale) {
  return std::abs(scale - std::lround(scale)) < DBL_EPSILON;
}

/// The source pixels destination pixel `d` overlaps and their weights, in source order.
std::vector<std::pair<int, float>> overlaps(int source, int d, double scale) {
  const double begin = d * scale, end = begin + scale;
  const double cell = std::min(scale, source - begin);
  const int whole_end = std::min(static_cast<int>(std::floor(end)), source - 1);
  const int whole_begin = std::min(static_cast<int>(std::ceil(begin)), whole_end);
  std::vector<std::pair<int, float>> taps;
  if (whole_begin - begin > kMinPartial) {
    taps.emplace_back(whole_begin - 1, static_cast<float>((whole_begin - begin) / cell));
  }
  for (int s = whole_begin; s < whole_end; ++s)
    taps.emplace_back(s, static_cast<float>(1.0 / cell));
  if (end - whole_end > kMinPartial) {
    taps.emplace_back(whole_end,
                      static_cast<float>(std::min(std::min(end - whole_end, 1.0), cell) / cell));
  }
  return taps;
}

}  // namespace

AreaShrinker::AreaShrinker(cv::Size from, cv::Size to) : from_(from), to_(to) {
  if (to.width < 1 || to.height < 1 || to.width > from.width || to.height > from.height) {
    throw InputError(fmt::format("area shrinking: cannot shrink {}x{} to {}x{}", from.width,
                                 from.height, to.width, to.height));
  }
  whole_factors_ = isWholeFactor(areaScale(from.width, to.width)) &&
                   isWholeFactor(areaScale(from.height, to.height));
  x_ = axisTable(from.width, to.width);
  y_ = axisTable(from.height, to.height);
}

AreaShrinker::Axis AreaShrinker::axisTable(int source, int destination) {
  const double scale = areaScale(source, destination);
  std::vector<std::vector<std::pair<int, float>>> all;
  Axis axis;
  for (int d = 0; d < destination; ++d) {
    all.push_back(overlaps(source, d, scale));
    axis.taps = std::max(axis.taps, static_cast<int>(all.back().size()));
  }
  const auto taps = static_cast<std::size_t>(axis.taps);
  axis.weights.assign(all.size() * taps, 0.0f);
  for (std::size_t d = 0; d < all.size(); ++d) {
    axis.first.push_back(all[d].front().first);
    for (std::size_t t = 0; t < all[d].size(); ++t)
      axis.weights[d * taps + t] = all[d][t].second;
  }
  return axis;
}

namespace {

/// The 16 bytes of `bytes` as floats, to out[0..15].
void storeAsFloats(const cv::v_uint8x16& bytes, float* out) {
  cv::v_uint16x8 lo, hi;
  cv::v_expand(bytes, lo, hi);
  cv::v_uint32x4 a, b, c, d;
  cv::v_expand(lo, a, b);
  cv::v_expand(hi, c, d);
  cv::v_store(out, cv::v_cvt_f32(cv::v_reinterpret_as_s32(a)));
  cv::v_store(out + 4, cv::v_cvt_f32(cv::v_reinterpret_as_s32(b)));
  cv::v_store(out + 8, cv::v_cvt_f32(cv::v_reinterpret_as_s32(c)));
  cv::v_store(out + 12, cv::v_cvt_f32(cv::v_reinterpret_as_s32(d)));
}

/// Converts `width` gray levels to float.
void toFloat(const std::uint8_t* row, int width, float* out) {
  int x = 0;
  for (; x + 16 <= width; x += 16)
    storeAsFloats(cv::v_load(row + x), out + x);
  for (; x < width; ++x)
    out[x] = static_cast<float>(row[x]);
}

/// Four rows as float, interleaved: out[4 x + r] = rows[r][x].
void interleaveFour(const std::uint8_t* const rows[4], int width, float* out) {
  int x = 0;
  for (; x + 16 <= width; x += 16, out += 64) {
    cv::v_uint8x16 r01a, r01b, r23a, r23b;
    cv::v_zip(cv::v_load(rows[0] + x), cv::v_load(rows[1] + x), r01a, r01b);
    cv::v_zip(cv::v_load(rows[2] + x), cv::v_load(rows[3] + x), r23a, r23b);
    cv::v_uint16x8 q[4];  // each: the four rows' bytes of four columns
    cv::v_zip(cv::v_reinterpret_as_u16(r01a), cv::v_reinterpret_as_u16(r23a), q[0], q[1]);
    cv::v_zip(cv::v_reinterpret_as_u16(r01b), cv::v_reinterpret_as_u16(r23b), q[2], q[3]);
    for (int k = 0; k < 4; ++k)
      storeAsFloats(cv::v_reinterpret_as_u8(q[k]), out + 16 * k);
  }
  for (; x < width; ++x, out += 4)
    for (int r = 0; r < 4; ++r)
      out[r] = static_cast<float>(rows[r][x]);
}

/// out[d] = sum over t of s[first[d] + t] * w[d * taps + t], added in tap order from 0. Taps > 0
/// fixes the number of taps at compile time (then taps == Taps).
template <int Taps>
void weightedSums(const float* s, const std::vector<int>& first, const float* w, int taps,
                  float* out) {
  if constexpr (Taps > 0) taps = Taps;
  for (std::size_t d = 0; d < first.size(); ++d, w += taps) {
    const float* p = s + first[d];
    float sum = 0.0f;
    for (int t = 0; t < taps; ++t)
      sum += p[t] * w[t];
    out[d] = sum;
  }
}

/// weightedSums of four interleaved rows (interleaveFour) at once, written to out[0..3].
template <int Taps>
void weightedSumsOfFour(const float* s, const std::vector<int>& first, const float* w, int taps,
                        float* const out[4]) {
  if constexpr (Taps > 0) taps = Taps;
  const std::size_t n = first.size();
  std::size_t d = 0;
  const auto sumAt = [&](std::size_t i) {
    const float* p = s + 4 * static_cast<std::size_t>(first[i]);
    const float* wi = w + i * static_cast<std::size_t>(taps);
    cv::v_float32x4 sum = cv::v_setzero_f32();
    for (int t = 0; t < taps; ++t)
      sum = sum + cv::v_load(p + 4 * t) * cv::v_setall_f32(wi[t]);
    return sum;  // lane r: row r
  };
  for (; d + 4 <= n; d += 4) {
    cv::v_float32x4 r0, r1, r2, r3;
    cv::v_transpose4x4(sumAt(d), sumAt(d + 1), sumAt(d + 2), sumAt(d + 3), r0, r1, r2, r3);
    cv::v_store(out[0] + d, r0);
    cv::v_store(out[1] + d, r1);
    cv::v_store(out[2] + d, r2);
    cv::v_store(out[3] + d, r3);
  }
  for (; d < n; ++d) {
    float lanes[4];
    cv::v_store(lanes, sumAt(d));
    for (int r = 0; r < 4; ++r)
      out[r][d] = lanes[r];
  }
}

/// Calls f(std::integral_constant<int, T>) with T = taps where a kernel is unrolled for that
/// number of taps (2, 3: factors up to 2), else T = 0 (any number).
template <typename F>
void withTaps(int taps, F&& f) {
  switch (taps) {
    case 2:
      f(std::integral_constant<int, 2>{});
      break;
    case 3:
      f(std::integral_constant<int, 3>{});
      break;
    default:
      f(std::integral_constant<int, 0>{});
      break;
  }
}

/// sum[x] += beta * h[x].
void addWeighted(float beta, const float* h, int width, float* sum) {
  const cv::v_float32x4 b = cv::v_setall_f32(beta);
  int x = 0;
  for (; x + 4 <= width; x += 4)
    cv::v_store(sum + x, cv::v_load(sum + x) + b * cv::v_load(h + x));
  for (; x < width; ++x)
    sum[x] += beta * h[x];
}

/// out[x] = the nearest gray level to sum[x] (ties to even, clamped to [0, 255]).
void storeRounded(const float* sum, int width, std::uint8_t* out) {
  int x = 0;
  for (; x + 16 <= width; x += 16) {
    const cv::v_int16x8 lo =
        cv::v_pack(cv::v_round(cv::v_load(sum + x)), cv::v_round(cv::v_load(sum + x + 4)));
    const cv::v_int16x8 hi =
        cv::v_pack(cv::v_round(cv::v_load(sum + x + 8)), cv::v_round(cv::v_load(sum + x + 12)));
    cv::v_store(out + x, cv::v_pack_u(lo, hi));
  }
  for (; x < width; ++x)
    out[x] = cv::saturate_cast<std::uint8_t>(sum[x]);
}

}  // namespace

struct AreaShrinker::RowRing {
  RowRing(int slot_count, int row_width)
      : slots(slot_count),
        width(row_width),
        data(static_cast<std::size_t>(slot_count * row_width)) {}
  float* row(int r) { return data.data() + static_cast<std::size_t>((r % slots) * width); }
  int slots, width;
  std::vector<float> data;
};

int AreaShrinker::sumRows(const cv::Mat& src, int row, std::vector<float>& scratch,
                          RowRing& ring) const {
  const float* w = x_.weights.data();
  const int taps = x_.taps;
  if (row + 4 > from_.height) {
    toFloat(src.ptr<std::uint8_t>(row), from_.width, scratch.data());
    float* out = ring.row(row);
    withTaps(taps, [&](auto fixed) {
      weightedSums<decltype(fixed)::value>(scratch.data(), x_.first, w, taps, out);
    });
    return 1;
  }
  const std::uint8_t* const rows[4] = {src.ptr<std::uint8_t>(row), src.ptr<std::uint8_t>(row + 1),
                                       src.ptr<std::uint8_t>(row + 2),
                                       src.ptr<std::uint8_t>(row + 3)};
  float* const out[4] = {ring.row(row), ring.row(row + 1), ring.row(row + 2), ring.row(row + 3)};
  interleaveFour(rows, from_.width, scratch.data());
  withTaps(taps, [&](auto fixed) {
    weightedSumsOfFour<decltype(fixed)::value>(scratch.data(), x_.first, w, taps, out);
  });
  return 4;
}

void AreaShrinker::apply(const cv::Mat& src, cv::Mat& dst) const {
  if (src.type() != CV_8UC1 || src.size() != from_) {
    throw InputError(
        fmt::format("area shrinking: expected a {}x{} CV_8UC1 image, got {}x{} type {}",
                    from_.width, from_.height, src.cols, src.rows, src.type()));
  }
  if (whole_factors_) {
    cv::resize(src, dst, to_, 0.0, 0.0, cv::INTER_AREA);
    return;
  }
  dst.create(to_, CV_8UC1);
  const int width = to_.width;
  // A destination row's source rows span at most y_.taps rows; four are summed at once.
  RowRing ring(y_.taps + 4, width);
  std::vector<float> scratch(static_cast<std::size_t>(4 * (from_.width + x_.taps)), 0.0f);
  std::vector<float> sum(static_cast<std::size_t>(width));
  const auto taps = static_cast<std::size_t>(y_.taps);
  int summed = 0;  // source rows [0, summed) are summed; the ring keeps the newest
  for (int d = 0; d < to_.height; ++d) {
    const float* beta = y_.weights.data() + static_cast<std::size_t>(d) * taps;
    const int first = y_.first[static_cast<std::size_t>(d)];
    std::fill(sum.begin(), sum.end(), 0.0f);
    // Past the rows this one overlaps the weights are 0: skipped.
    for (std::size_t t = 0; t < taps && beta[t] != 0.0f; ++t) {
      const int r = first + static_cast<int>(t);
      while (summed <= r)
        summed += sumRows(src, summed, scratch, ring);
      addWeighted(beta[t], ring.row(r), width, sum.data());
    }
    storeRounded(sum.data(), width, dst.ptr<std::uint8_t>(d));
  }
}

}  // namespace superdyna::features
