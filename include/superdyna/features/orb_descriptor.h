#pragma once
// Building blocks of ORB (Rublee et al., ICCV 2011): intensity-centroid orientation and steered
// (rotated) BRIEF descriptors.
//
// Sampling pattern: 256 point pairs drawn once, i.i.d. from an isotropic Gaussian with sigma =
// kOrbPatchSize / 5 = 6.2 px (BRIEF's "G II" strategy), truncated to the disc of radius
// kOrbPatchRadius (so any rotation keeps them inside the 31x31 patch), coordinates rounded to
// integers; a pair of identical points or a repeated test is redrawn. The generator is a seeded
// SplitMix64 stream with a hand-written Box-Muller transform (no standard distribution, whose
// output differs between standard libraries), so the pattern, and with it every descriptor, is the
// same everywhere (the test pins its first pairs). Steered sampling rounds with cvRound (nearest,
// ties to even).

#include <array>
#include <cstdint>
#include <opencv2/core.hpp>

namespace superdyna::features {

inline constexpr int kOrbPatchSize = 31;        ///< Side of the described patch [px at its level].
inline constexpr int kOrbPatchRadius = 15;      ///< Radius of the orientation / sampling disc [px].
inline constexpr int kOrbDescriptorBytes = 32;  ///< 256 bits.
/// Seed of the sampling pattern (changing it changes every descriptor).
inline constexpr std::uint64_t kBriefPatternSeed = 0x5D0B1EF5EEDULL;

/// One binary test: bit = I(p0) < I(p1), offsets in pixels from the keypoint (x right, y down).
struct BriefPair {
  std::int8_t x0 = 0, y0 = 0, x1 = 0, y1 = 0;
};

/// The 256 tests of the descriptor, bit i of the descriptor is test i (byte i / 8, bit i % 8,
/// least significant first). Every offset lies within kOrbPatchRadius of the centre.
const std::array<BriefPair, 256>& briefPattern();

/// Orientation [deg, in [0, 360)] of the intensity centroid of the disc of radius
/// kOrbPatchRadius around `center`: atan2(m01, m10) with m10 = sum x I, m01 = sum y I over the
/// disc (offsets from the centre). `image` is CV_8UC1 and `center` at least kOrbPatchRadius
/// pixels from every border (not checked in release builds).
float intensityCentroidAngle(const cv::Mat& image, cv::Point center);

/// Writes the kOrbDescriptorBytes-byte steered-BRIEF descriptor of `center` to `out`: each test
/// of briefPattern() is rotated by angle_deg (same convention as Keypoint::angle) and sampled at
/// the nearest pixel of `smoothed` (CV_8UC1, usually Gaussian-blurred). `center` must be at least
/// kOrbPatchRadius pixels from every border (not checked in release builds).
void computeSteeredBrief(const cv::Mat& smoothed, cv::Point center, float angle_deg,
                         std::uint8_t* out);

}  // namespace superdyna::features
