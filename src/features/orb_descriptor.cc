#include "superdyna/features/orb_descriptor.h"

#include <array>
#include <cassert>
#include <cmath>
#include <numbers>

namespace superdyna::features {

namespace {

/// SplitMix64: a tiny, fully specified 64-bit generator (same stream on every platform).
class SplitMix64 {
 public:
  explicit SplitMix64(std::uint64_t seed) : state_(seed) {}
  std::uint64_t next() {
    std::uint64_t z = (state_ += 0x9E3779B97F4A7C15ULL);
    z = (z ^ (z >> 30)) * 0xBF58476D1CE4E5B9ULL;
    z = (z ^ (z >> 27)) * 0x94D049BB133111EBULL;
    return z ^ (z >> 31);
  }
  /// Uniform in (0, 1): never 0, so its logarithm is finite.
  double uniformOpen() { return (static_cast<double>(next() >> 11) + 0.5) * 0x1.0p-53; }

 private:
  std::uint64_t state_;
};

/// A point of the pattern: Gaussian offsets (Box-Muller), rounded, inside the sampling disc.
cv::Point drawPoint(SplitMix64& rng, double sigma) {
  constexpr int kRadius2 = kOrbPatchRadius * kOrbPatchRadius;
  for (;;) {
    const double r = std::sqrt(-2.0 * std::log(rng.uniformOpen()));
    const double phi = 2.0 * std::numbers::pi * rng.uniformOpen();
    const int x = static_cast<int>(std::lround(sigma * r * std::cos(phi)));
    const int y = static_cast<int>(std::lround(sigma * r * std::sin(phi)));
    if (x * x + y * y <= kRadius2) return {x, y};
  }
}

bool samePair(const BriefPair& a, const BriefPair& b) {
  const bool same = a.x0 == b.x0 && a.y0 == b.y0 && a.x1 == b.x1 && a.y1 == b.y1;
  const bool swapped = a.x0 == b.x1 && a.y0 == b.y1 && a.x1 == b.x0 && a.y1 == b.y0;
  return same || swapped;
}

std::array<BriefPair, 256> makePattern() {
  constexpr double kSigma = kOrbPatchSize / 5.0;
  SplitMix64 rng(kBriefPatternSeed);
  std::array<BriefPair, 256> pattern{};
  for (std::size_t i = 0; i < pattern.size();) {
    const cv::Point p0 = drawPoint(rng, kSigma);
    const cv::Point p1 = drawPoint(rng, kSigma);
    if (p0 == p1) continue;
    const BriefPair pair{static_cast<std::int8_t>(p0.x), static_cast<std::int8_t>(p0.y),
                         static_cast<std::int8_t>(p1.x), static_cast<std::int8_t>(p1.y)};
    bool duplicate = false;
    for (std::size_t k = 0; k < i && !duplicate; ++k)
      duplicate = samePair(pattern[k], pair);
    if (duplicate) continue;
    pattern[i++] = pair;
  }
  return pattern;
}

/// Half width of the orientation disc on each row offset: the largest w with w^2 + dy^2 <= R^2.
std::array<int, kOrbPatchRadius + 1> discHalfWidths() {
  std::array<int, kOrbPatchRadius + 1> widths{};
  for (int dy = 0; dy <= kOrbPatchRadius; ++dy) {
    int w = 0;
    while ((w + 1) * (w + 1) + dy * dy <= kOrbPatchRadius * kOrbPatchRadius)
      ++w;
    widths[static_cast<std::size_t>(dy)] = w;
  }
  return widths;
}

}  // namespace

const std::array<BriefPair, 256>& briefPattern() {
  static const std::array<BriefPair, 256> pattern = makePattern();
  return pattern;
}

namespace {

/// The pattern's points as doubles, pair i's first point at 2 i and second at 2 i + 1.
constexpr std::size_t kPatternPoints = 512;
struct PatternPoints {
  std::array<double, kPatternPoints> x, y;
};

PatternPoints patternPoints() {
  PatternPoints points{};
  const auto& pattern = briefPattern();
  for (std::size_t i = 0; i < pattern.size(); ++i) {
    points.x[2 * i] = pattern[i].x0;
    points.y[2 * i] = pattern[i].y0;
    points.x[2 * i + 1] = pattern[i].x1;
    points.y[2 * i + 1] = pattern[i].y1;
  }
  return points;
}

}  // namespace

float intensityCentroidAngle(const cv::Mat& image, cv::Point center) {
  assert(image.type() == CV_8UC1);
  assert(center.x >= kOrbPatchRadius && center.y >= kOrbPatchRadius &&
         center.x + kOrbPatchRadius < image.cols && center.y + kOrbPatchRadius < image.rows);
  static const auto half_widths = discHalfWidths();
  const std::ptrdiff_t step = static_cast<std::ptrdiff_t>(image.step1());
  const std::uint8_t* c = image.ptr<std::uint8_t>(center.y) + center.x;
  long m10 = 0, m01 = 0;
  for (int dx = -kOrbPatchRadius; dx <= kOrbPatchRadius; ++dx)
    m10 += dx * c[dx];
  for (int dy = 1; dy <= kOrbPatchRadius; ++dy) {
    const int w = half_widths[static_cast<std::size_t>(dy)];
    const std::uint8_t* below = c + dy * step;
    const std::uint8_t* above = c - dy * step;
    long row_difference = 0;
    for (int dx = -w; dx <= w; ++dx) {
      m10 += dx * (below[dx] + above[dx]);
      row_difference += below[dx] - above[dx];
    }
    m01 += dy * row_difference;
  }
  if (m10 == 0 && m01 == 0) return 0.0f;
  double angle =
      std::atan2(static_cast<double>(m01), static_cast<double>(m10)) * 180.0 / std::numbers::pi;
  if (angle < 0.0) angle += 360.0;
  return angle >= 360.0 ? 0.0f : static_cast<float>(angle);
}

void computeSteeredBrief(const cv::Mat& smoothed, cv::Point center, float angle_deg,
                         std::uint8_t* out) {
  assert(smoothed.type() == CV_8UC1);
  assert(center.x >= kOrbPatchRadius && center.y >= kOrbPatchRadius &&
         center.x + kOrbPatchRadius < smoothed.cols && center.y + kOrbPatchRadius < smoothed.rows);
  static const PatternPoints points = patternPoints();
  const double angle = static_cast<double>(angle_deg) * std::numbers::pi / 180.0;
  const double cs = std::cos(angle), sn = std::sin(angle);
  const std::ptrdiff_t step = static_cast<std::ptrdiff_t>(smoothed.step1());
  const std::uint8_t* c = smoothed.ptr<std::uint8_t>(center.y) + center.x;
  // Rotating a point of the disc keeps it in the disc, and rounding keeps |offset| <= radius.
  // cvRound rounds to nearest (ties to even): deterministic and much faster than std::lround.
  // All offsets first, then the tests: the loads of the second loop do not wait on each other.
  std::array<std::ptrdiff_t, kPatternPoints> offsets;
  for (std::size_t i = 0; i < kPatternPoints; ++i) {
    const double x = points.x[i], y = points.y[i];
    offsets[i] = cvRound(sn * x + cs * y) * step + cvRound(cs * x - sn * y);
  }
  for (std::size_t byte = 0; byte < static_cast<std::size_t>(kOrbDescriptorBytes); ++byte) {
    unsigned value = 0;
    for (std::size_t bit = 0; bit < 8; ++bit) {
      const std::size_t pair = 2 * (byte * 8 + bit);
      value |= static_cast<unsigned>(c[offsets[pair]] < c[offsets[pair + 1]]) << bit;
    }
    out[byte] = static_cast<std::uint8_t>(value);
  }
}

}  // namespace superdyna::features
