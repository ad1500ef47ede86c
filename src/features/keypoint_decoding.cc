#include "superdyna/features/keypoint_decoding.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <opencv2/imgproc.hpp>

#include "superdyna/core/error.h"

namespace superdyna::features {

namespace {

/// Whether no pixel of a cell can have heat above `min_heat`, from the cell's largest pixel logit
/// and its dustbin logit: the heat of pixel c is e^l_c / sum_k e^l_k <= e^l_c / (e^l_c +
/// e^l_dustbin) = sigmoid(l_c - l_dustbin). `max_gap` = logit(min_heat) less a margin that keeps
/// rounding in the softmax from mattering.
bool cellIsBelowHeat(float max_pixel_logit, float dustbin_logit, float max_gap) {
  return max_pixel_logit - dustbin_logit < max_gap;
}

/// Softmax of one cell's logits into its cell x cell block of `heatmap`, dustbin dropped.
void writeCellHeat(const DenseMap& logits, int i, int j, int cell, float max_logit,
                   std::vector<float>& e, cv::Mat& heatmap) {
  float sum = 0.0f;
  for (int c = 0; c < logits.channels; ++c) {
    e[static_cast<std::size_t>(c)] = std::exp(logits.at(c, i, j) - max_logit);
    sum += e[static_cast<std::size_t>(c)];
  }
  for (int r = 0; r < cell; ++r) {
    float* row = heatmap.ptr<float>(i * cell + r) + j * cell;
    for (int col = 0; col < cell; ++col)
      row[col] = e[static_cast<std::size_t>(r * cell + col)] / sum;
  }
}

}  // namespace

cv::Mat cellLogitsToHeatmap(const DenseMap& logits, int cell, float min_heat) {
  if (cell < 1 || logits.channels != cell * cell + 1) {
    throw InputError(
        fmt::format("keypoint logits have {} channels, expected {} ({}x{} cell + "
                    "dustbin)",
                    logits.channels, cell * cell + 1, cell, cell));
  }
  const int pixels = cell * cell;  // channel `pixels` is the dustbin
  const bool skip_cold = min_heat > 0.0f;
  // 1e-3 in log space: far above float rounding in the softmax, far below any real margin.
  const float max_gap =
      skip_cold ? static_cast<float>(std::log(min_heat / (1.0 - min_heat))) - 1e-3f : 0.0f;
  cv::Mat heatmap(logits.rows * cell, logits.cols * cell, CV_32FC1, cv::Scalar(0.0f));
  std::vector<float> e(static_cast<std::size_t>(logits.channels));
  // Per row of cells, channel by channel: the logits of one channel are contiguous along a row.
  std::vector<float> max_pixel(static_cast<std::size_t>(logits.cols));
  const std::size_t plane = static_cast<std::size_t>(logits.rows) * logits.cols;
  for (int i = 0; i < logits.rows; ++i) {
    const float* row0 = logits.data + static_cast<std::size_t>(i) * logits.cols;
    std::fill(max_pixel.begin(), max_pixel.end(), -std::numeric_limits<float>::infinity());
    for (int c = 0; c < pixels; ++c) {
      const float* row = row0 + static_cast<std::size_t>(c) * plane;
      for (int j = 0; j < logits.cols; ++j)
        max_pixel[static_cast<std::size_t>(j)] =
            std::max(max_pixel[static_cast<std::size_t>(j)], row[j]);
    }
    const float* dustbin = row0 + static_cast<std::size_t>(pixels) * plane;
    for (int j = 0; j < logits.cols; ++j) {
      const float max_pixel_logit = max_pixel[static_cast<std::size_t>(j)];
      if (skip_cold && cellIsBelowHeat(max_pixel_logit, dustbin[j], max_gap)) continue;
      writeCellHeat(logits, i, j, cell, std::max(max_pixel_logit, dustbin[j]), e, heatmap);
    }
  }
  return heatmap;
}

std::vector<ScoredPixel> localMaxima(const cv::Mat& heatmap, int window, float threshold) {
  if (window < 1 || window % 2 == 0) {
    throw OptionError("nms_window", fmt::format("must be odd and >= 1, got {}", window));
  }
  CV_Assert(heatmap.type() == CV_32FC1);
  // Only pixels above the threshold can be kept, and few are: compare those with their window
  // (clipped to the heatmap, as a max-pool with -inf padding) instead of max-pooling everything.
  const int half = window / 2;
  std::vector<ScoredPixel> points;
  for (int y = 0; y < heatmap.rows; ++y) {
    const float* h = heatmap.ptr<float>(y);
    const int y0 = std::max(0, y - half), y1 = std::min(heatmap.rows - 1, y + half);
    for (int x = 0; x < heatmap.cols; ++x) {
      if (!(h[x] > threshold)) continue;
      const int x0 = std::max(0, x - half), x1 = std::min(heatmap.cols - 1, x + half);
      bool is_max = true;
      for (int v = y0; v <= y1 && is_max; ++v) {
        const float* n = heatmap.ptr<float>(v);
        for (int u = x0; u <= x1; ++u) {
          if (n[u] > h[x]) {
            is_max = false;
            break;
          }
        }
      }
      if (is_max) points.push_back({x, y, h[x]});
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

namespace {

/// sortByScore()'s order: a strict total order on pixels with distinct coordinates.
bool scoresBefore(const ScoredPixel& a, const ScoredPixel& b) {
  if (a.score != b.score) return a.score > b.score;
  if (a.y != b.y) return a.y < b.y;
  return a.x < b.x;
}

}  // namespace

void sortByScore(std::vector<ScoredPixel>& points) {
  std::sort(points.begin(), points.end(), scoresBefore);
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
  if (grid_cell_px <= 0 && k > 0 && static_cast<int>(points.size()) > k) {
    // The order is total, so the k first of a partial sort are those of a full sort.
    std::partial_sort(points.begin(), points.begin() + k, points.end(), scoresBefore);
    points.resize(static_cast<std::size_t>(k));
    return points;
  }
  sortByScore(points);
  if (k <= 0 || static_cast<int>(points.size()) <= k) return points;
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

std::vector<Eigen::Vector2d> refineSoftArgmax(const cv::Mat& scores,
                                              const std::vector<ScoredPixel>& points, int radius,
                                              float temperature) {
  if (radius < 0) throw OptionError("radius", fmt::format("must be >= 0, got {}", radius));
  if (!(temperature > 0.0f)) {
    throw OptionError("temperature", fmt::format("must be > 0, got {}", temperature));
  }
  CV_Assert(scores.type() == CV_32FC1);
  std::vector<Eigen::Vector2d> refined;
  refined.reserve(points.size());
  for (const auto& p : points) {
    const int x0 = std::max(0, p.x - radius), x1 = std::min(scores.cols - 1, p.x + radius);
    const int y0 = std::max(0, p.y - radius), y1 = std::min(scores.rows - 1, p.y + radius);
    float peak = -std::numeric_limits<float>::infinity();
    for (int y = y0; y <= y1; ++y)
      for (int x = x0; x <= x1; ++x)
        peak = std::max(peak, scores.at<float>(y, x));
    double sum = 0.0, sx = 0.0, sy = 0.0;
    for (int y = y0; y <= y1; ++y) {
      for (int x = x0; x <= x1; ++x) {
        const double w = std::exp((scores.at<float>(y, x) - peak) / temperature);
        sum += w;
        sx += w * x;
        sy += w * y;
      }
    }
    refined.emplace_back(sx / sum, sy / sum);
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
  // Channel-major loops (contiguous); every cell still sums its channels in order 0, 1, ...
  std::vector<double> norm2(plane, 0.0);
  for (int c = 0; c < map.channels; ++c) {
    const float* channel = out.data() + static_cast<std::size_t>(c) * plane;
    for (std::size_t p = 0; p < plane; ++p) {
      const double value = channel[p];
      norm2[p] += value * value;
    }
  }
  std::vector<double> scale(plane, 1.0);  // a zero vector stays as it is
  for (std::size_t p = 0; p < plane; ++p)
    if (norm2[p] > 0.0) scale[p] = 1.0 / std::sqrt(norm2[p]);
  for (int c = 0; c < map.channels; ++c) {
    float* channel = out.data() + static_cast<std::size_t>(c) * plane;
    for (std::size_t p = 0; p < plane; ++p)
      if (norm2[p] > 0.0) channel[p] = static_cast<float>(channel[p] * scale[p]);
  }
  return out;
}

Eigen::Array2d ImageFit::pixelScale() const {
  return {static_cast<double>(original.width) / content.width,
          static_cast<double>(original.height) / content.height};
}

Eigen::Vector2d ImageFit::toOriginal(const Eigen::Vector2d& network_pixel) const {
  if (content == original) return network_pixel;
  return ((network_pixel.array() + 0.5) * pixelScale() - 0.5).matrix();
}

void checkInputScale(double scale, const std::string& key) {
  if (!(scale > 0.0 && scale <= 1.0))
    throw OptionError(key, fmt::format("must be in (0, 1], got {}", scale));
}

ImageFit planFit(cv::Size original, int multiple, FitMode mode, double scale) {
  if (multiple < 1)
    throw OptionError("size multiple", fmt::format("must be >= 1, got {}", multiple));
  checkInputScale(scale);
  if (original.width <= 0 || original.height <= 0) {
    throw InputError(fmt::format("empty image ({}x{})", original.width, original.height));
  }
  const auto scaled = [&](int side) {
    return std::max(1, static_cast<int>(std::lround(side * scale)));
  };
  const cv::Size content(scaled(original.width), scaled(original.height));
  if (mode == FitMode::kPad) {
    const auto up = [&](int side) { return (side + multiple - 1) / multiple * multiple; };
    return ImageFit{mode, original, content, cv::Size(up(content.width), up(content.height))};
  }
  const auto down = [&](int side) { return std::max(multiple, side / multiple * multiple); };
  const cv::Size network(down(content.width), down(content.height));
  return ImageFit{mode, original, network, network};
}

cv::Mat applyFit(const cv::Mat& gray, const ImageFit& fit) {
  CV_Assert(gray.size() == fit.original);
  if (fit.content == fit.original && fit.network == fit.original) return gray;
  if (fit.mode == FitMode::kResize) {
    cv::Mat out;
    cv::resize(gray, out, fit.network, 0.0, 0.0, cv::INTER_LINEAR);
    return out;
  }
  cv::Mat scaled = gray;
  // Area averaging for a smaller image: no aliasing of fine texture into false corners.
  if (fit.content != fit.original) cv::resize(gray, scaled, fit.content, 0.0, 0.0, cv::INTER_AREA);
  const int right = fit.network.width - fit.content.width;
  const int bottom = fit.network.height - fit.content.height;
  // Reflection needs the pad to be smaller than the image; replicate beyond that.
  const int border =
      (right < scaled.cols && bottom < scaled.rows) ? cv::BORDER_REFLECT_101 : cv::BORDER_REPLICATE;
  cv::Mat out;
  cv::copyMakeBorder(scaled, out, 0, bottom, 0, right, border);
  return out;
}

}  // namespace superdyna::features
