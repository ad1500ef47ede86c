#pragma once
// Images and geometry shared by the feature tests.

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>

#include "superdyna/sim/texture.h"

namespace superdyna::features::test {

/// A seeded procedural texture image (rich in corners at several scales), CV_8UC1.
cv::Mat texturedImage(int width, int height, std::uint64_t seed,
                      sim::TextureStyle style = sim::TextureStyle::kIndoor);

/// The 2x3 affine map `M` applied to a pixel.
Eigen::Vector2d applyAffine(const cv::Mat& M, const Eigen::Vector2d& p);

/// A crop of size `crop` centred in `big`, and the same crop of `big` warped by the rotation
/// (counter-clockwise on screen, degrees) and scale about big's centre. `M_out` receives the 2x3
/// map from crop pixels of the first image to crop pixels of the second.
void warpedPair(const cv::Mat& big, cv::Size crop, double angle_deg, double scale, cv::Mat* first,
                cv::Mat* second, cv::Mat* M_out);

}  // namespace superdyna::features::test
