#include "feature_test_util.h"

#include <opencv2/imgproc.hpp>

namespace superdyna::features::test {

cv::Mat texturedImage(int width, int height, std::uint64_t seed, sim::TextureStyle style) {
  sim::ProceduralTextureOptions options;
  options.width = width;
  options.height = height;
  options.seed = seed;
  options.style = style;
  return sim::Texture::procedural(options).image().clone();
}

Eigen::Vector2d applyAffine(const cv::Mat& M, const Eigen::Vector2d& p) {
  return {M.at<double>(0, 0) * p.x() + M.at<double>(0, 1) * p.y() + M.at<double>(0, 2),
          M.at<double>(1, 0) * p.x() + M.at<double>(1, 1) * p.y() + M.at<double>(1, 2)};
}

void warpedPair(const cv::Mat& big, cv::Size crop, double angle_deg, double scale, cv::Mat* first,
                cv::Mat* second, cv::Mat* M_out) {
  const cv::Point2f centre(0.5f * (big.cols - 1), 0.5f * (big.rows - 1));
  const cv::Mat M = cv::getRotationMatrix2D(centre, angle_deg, scale);
  cv::Mat warped;
  cv::warpAffine(big, warped, M, big.size(), cv::INTER_LINEAR, cv::BORDER_REFLECT_101);
  const cv::Rect roi((big.cols - crop.width) / 2, (big.rows - crop.height) / 2, crop.width,
                     crop.height);
  *first = big(roi).clone();
  *second = warped(roi).clone();
  // crop -> big: +offset; big -> warped: M; warped -> crop: -offset.
  cv::Mat shifted = M.clone();
  const double ox = roi.x, oy = roi.y;
  shifted.at<double>(0, 2) += M.at<double>(0, 0) * ox + M.at<double>(0, 1) * oy - ox;
  shifted.at<double>(1, 2) += M.at<double>(1, 0) * ox + M.at<double>(1, 1) * oy - oy;
  *M_out = shifted;
}

}  // namespace superdyna::features::test
