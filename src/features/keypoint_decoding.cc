#include "superdyna/features/keypoint_decoding.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "superdyna/core/error.h"

namespace superdyna::features {

cv::Mat cellLogitsToHeatmap(const DenseMap& logits, int cell) {
  if (cell < 1 || logits.channels != cell * cell + 1) {
    throw InputError(
        fmt::format("keypoint logits have {} channels, expected {} ({}x{} cell + "
                    "dustbin)",
                    logits.channels, cell * cell + 1, cell, cell));
  }
  cv::Mat heatmap(logits.rows * cell, logits.cols * cell, CV_32FC1);
  std::vector<float> e(static_cast<std::size_t>(logits.channels));
  for (int i = 0; i < logits.rows; ++i) {
    for (int j = 0; j < logits.cols; ++j) {
      float max_logit = -std::numeric_limits<float>::infinity();
      for (int c = 0; c < logits.channels; ++c)
        max_logit = std::max(max_logit, logits.at(c, i, j));
      float sum = 0.0f;
      for (int c = 0; c < logits.channels; ++c) {
        e[static_cast<std::size_t>(c)] = std::exp(logits.at(c, i, j) - max_logit);
        sum += e[static_cast<std::size_t>(c)];
      }
      for (int c = 0; c < cell * cell; ++c) {
        heatmap.at<float>(i * cell + c / cell, j * cell + c % cell) =
            e[static_cast<std::size_t>(c)] / sum;
      }
    }
  }
  return heatmap;
}

std::vector<ScoredPixel> localMaxima(const cv::Mat& heatmap, int window, float threshold) {
  if (window < 1 || window % 2 == 0) {
    throw OptionError("nms_window", fmt::format("must be odd and >= 1, got {}", window));
  }
  CV_Assert(heatmap.type() == CV_32FC1);
  // OpenCV filters read beyond a submatrix's edge into its parent: work on a copy then.
  const cv::Mat own = heatmap.isSubmatrix() ? heatmap.clone() : heatmap;
  cv::Mat pooled;
  // Dilation is an exact maximum; outside the image it uses -inf (max-pool padding).
  cv::dilate(own, pooled, cv::getStructuringElement(cv::MORPH_RECT, {window, window}),
             cv::Point(-1, -1), 1, cv::BORDER_CONSTANT, cv::morphologyDefaultBorderValue());
  std::vector<ScoredPixel> points;
  for (int y = 0; y < own.rows; ++y) {
    const float* h = own.ptr<float>(y);
    const float* m = pooled.ptr<float>(y);
    for (int x = 0; x < own.cols; ++x) {
      if (h[x] > threshold && h[x] == m[x]) points.push_back({x, y, h[x]});
    }
  }
  return points;
}

std::vector<ScoredPixel> pixelsAtLeast(const cv::Mat& heatmap, float threshold) {
  CV_Assert(heatmap.type() == CV_32FC1);
  std::vector<ScoredPixel> points;
  for (int y = 0; y < heatmap.rows; ++y) {
    const float* h = heatmap.ptr<float>(y);
    for (int x = 0; x < heatmap.cols; ++x) {
      if (h[x] >= threshold) points.push_back({x, y, h[x]});
    }
  }
  return points;
}

void sortByScore(std::vector<ScoredPixel>& points) {
  std::sort(points.begin(), points.end(), [](const ScoredPixel& a, const ScoredPixel& b) {
    if (a.score != b.score) return a.score > b.score;
    if (a.y != b.y) return a.y < b.y;
    return a.x < b.x;
  });
}

std::vector<ScoredPixel> suppressNonMaxima(std::vector<ScoredPixel> candidates, int radius,
                                           cv::Size size) {
  if (radius < 0) throw OptionError("nms_radius", fmt::format("must be >= 0, got {}", radius));
  sortByScore(candidates);
  if (radius == 0) return candidates;
  // taken(y, x) = 1 where a kept candidate's square covers the pixel.
  cv::Mat taken = cv::Mat::zeros(size, CV_8UC1);
  std::vector<ScoredPixel> kept;
  for (const auto& p : candidates) {
    if (p.x < 0 || p.y < 0 || p.x >= size.width || p.y >= size.height) {
      throw InputError(fmt::format("candidate ({}, {}) outside the {}x{} heatmap", p.x, p.y,
                                   size.width, size.height));
    }
    if (taken.at<std::uint8_t>(p.y, p.x) != 0) continue;
    kept.push_back(p);
    const int x0 = std::max(0, p.x - radius), x1 = std::min(size.width - 1, p.x + radius);
    const int y0 = std::max(0, p.y - radius), y1 = std::min(size.height - 1, p.y + radius);
    taken(cv::Range(y0, y1 + 1), cv::Range(x0, x1 + 1)).setTo(1);
  }
  return kept;
}

std::vector<ScoredPixel> keepInside(const std::vector<ScoredPixel>& points, int border,
                                    cv::Size valid) {
  std::vector<ScoredPixel> inside;
  for (const auto& p : points) {
    if (p.x >= border && p.y >= border && p.x < valid.width - border &&
        p.y < valid.height - border) {
      inside.push_back(p);
    }
  }
  return inside;
}

std::vector<ScoredPixel> selectTopK(std::vector<ScoredPixel> points, int k, int grid_cell_px) {
  sortByScore(points);
  if (k <= 0 || static_cast<int>(points.size()) <= k) return points;
  if (grid_cell_px <= 0) {
    points.resize(static_cast<std::size_t>(k));
    return points;
  }
  // Rank of each point within its grid cell, in score order.
  int max_x = 0, max_y = 0;
  for (const auto& p : points) {
    max_x = std::max(max_x, p.x);
    max_y = std::max(max_y, p.y);
  }
  const int cols = max_x / grid_cell_px + 1;
  const int rows = max_y / grid_cell_px + 1;
  std::vector<int> count(static_cast<std::size_t>(cols) * rows, 0);
  std::vector<int> rank(points.size());
  for (std::size_t i = 0; i < points.size(); ++i) {
    const int cell = (points[i].y / grid_cell_px) * cols + points[i].x / grid_cell_px;
    rank[i] = count[static_cast<std::size_t>(cell)]++;
  }
  std::vector<std::size_t> order(points.size());
  for (std::size_t i = 0; i < order.size(); ++i)
    order[i] = i;
  // points are in score order already, so a stable sort by rank keeps it within each rank.
  std::stable_sort(order.begin(), order.end(),
                   [&](std::size_t a, std::size_t b) { return rank[a] < rank[b]; });
  std::vector<ScoredPixel> chosen;
  chosen.reserve(static_cast<std::size_t>(k));
  for (int i = 0; i < k; ++i)
    chosen.push_back(points[order[static_cast<std::size_t>(i)]]);
  sortByScore(chosen);
  return chosen;
}

std::vector<Eigen::Vector2d> refineSubpixel(const cv::Mat& heatmap,
                                            const std::vector<ScoredPixel>& points, int radius) {
  if (radius < 0) {
    throw OptionError("subpixel_radius", fmt::format("must be >= 0, got {}", radius));
  }
  CV_Assert(heatmap.type() == CV_32FC1);
  std::vector<Eigen::Vector2d> refined;
  refined.reserve(points.size());
  for (const auto& p : points) {
    const int x0 = std::max(0, p.x - radius), x1 = std::min(heatmap.cols - 1, p.x + radius);
    const int y0 = std::max(0, p.y - radius), y1 = std::min(heatmap.rows - 1, p.y + radius);
    float floor = std::numeric_limits<float>::infinity();
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        floor = std::min(floor, heatmap.at<float>(y, x));
    double sum = 0.0, sx = 0.0, sy = 0.0;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double w = heatmap.at<float>(y, x) - floor;
        sum += w;
        sx += w * x;
        sy += w * y;
      }
    }
    refined.push_back(sum > 0.0 ? Eigen::Vector2d(sx / sum, sy / sum) : Eigen::Vector2d(p.x, p.y));
  }
  return refined;
}

Eigen::Vector2d pixelToMap(const Eigen::Vector2d& pixel, int stride) {
  return (pixel.array() + 0.5) / stride - 0.5;
}

float sampleBilinear(const DenseMap& map, int channel, double u, double v) {
  u = std::clamp(u, 0.0, static_cast<double>(map.cols - 1));
  v = std::clamp(v, 0.0, static_cast<double>(map.rows - 1));
  const int x0 = static_cast<int>(std::floor(u));
  const int y0 = static_cast<int>(std::floor(v));
  const int x1 = std::min(x0 + 1, map.cols - 1);
  const int y1 = std::min(y0 + 1, map.rows - 1);
  const double wx = u - x0;
  const double wy = v - y0;
  const double top = (1.0 - wx) * map.at(channel, y0, x0) + wx * map.at(channel, y0, x1);
  const double bottom = (1.0 - wx) * map.at(channel, y1, x0) + wx * map.at(channel, y1, x1);
  return static_cast<float>((1.0 - wy) * top + wy * bottom);
}

cv::Mat sampleDescriptors(const DenseMap& map, const std::vector<Eigen::Vector2d>& pixels,
                          int stride) {
  cv::Mat descriptors(static_cast<int>(pixels.size()), map.channels, CV_32FC1);
  for (int i = 0; i < descriptors.rows; ++i) {
    const Eigen::Vector2d uv = pixelToMap(pixels[static_cast<std::size_t>(i)], stride);
    float* row = descriptors.ptr<float>(i);
    double norm2 = 0.0;
    for (int c = 0; c < map.channels; ++c) {
      row[c] = sampleBilinear(map, c, uv.x(), uv.y());
      norm2 += static_cast<double>(row[c]) * row[c];
    }
    if (norm2 > 0.0) {
      const double inv = 1.0 / std::sqrt(norm2);
      for (int c = 0; c < map.channels; ++c)
        row[c] = static_cast<float>(row[c] * inv);
    }
  }
  return descriptors;
}

std::vector<float> normalizeCells(const DenseMap& map) {
  const std::size_t plane = static_cast<std::size_t>(map.rows) * map.cols;
  std::vector<float> out(map.data, map.data + plane * static_cast<std::size_t>(map.channels));
  for (std::size_t p = 0; p < plane; ++p) {
    double norm2 = 0.0;
    for (int c = 0; c < map.channels; ++c) {
      const double value = out[static_cast<std::size_t>(c) * plane + p];
      norm2 += value * value;
    }
    if (norm2 <= 0.0) continue;
    const double inv = 1.0 / std::sqrt(norm2);
    for (int c = 0; c < map.channels; ++c) {
      float& value = out[static_cast<std::size_t>(c) * plane + p];
      value = static_cast<float>(value * inv);
    }
  }
  return out;
}

Eigen::Vector2d ImageFit::toOriginal(const Eigen::Vector2d& network_pixel) const {
  if (mode == FitMode::kPad) return network_pixel;
  const Eigen::Array2d scale(static_cast<double>(original.width) / network.width,
                             static_cast<double>(original.height) / network.height);
  return ((network_pixel.array() + 0.5) * scale - 0.5).matrix();
}

ImageFit planFit(cv::Size original, int multiple, FitMode mode) {
  if (multiple < 1)
    throw OptionError("size multiple", fmt::format("must be >= 1, got {}", multiple));
  if (original.width <= 0 || original.height <= 0) {
    throw InputError(fmt::format("empty image ({}x{})", original.width, original.height));
  }
  const auto fit = [&](int side) {
    if (mode == FitMode::kPad) return (side + multiple - 1) / multiple * multiple;
    return std::max(multiple, side / multiple * multiple);
  };
  return ImageFit{mode, original, cv::Size(fit(original.width), fit(original.height))};
}

cv::Mat applyFit(const cv::Mat& gray, const ImageFit& fit) {
  CV_Assert(gray.size() == fit.original);
  if (fit.network == fit.original) return gray;
  cv::Mat out;
  if (fit.mode == FitMode::kPad) {
    const int right = fit.network.width - fit.original.width;
    const int bottom = fit.network.height - fit.original.height;
    // Reflection needs the pad to be smaller than the image; replicate beyond that.
    const int border =
        (right < gray.cols && bottom < gray.rows) ? cv::BORDER_REFLECT_101 : cv::BORDER_REPLICATE;
    cv::copyMakeBorder(gray, out, 0, bottom, 0, right, border);
  } else {
    cv::resize(gray, out, fit.network, 0.0, 0.0, cv::INTER_LINEAR);
  }
  return out;
}

}  // namespace superdyna::features
