#pragma once
// The steps that turn the dense outputs of a SuperPoint-style keypoint network (XFeat,
// SuperPoint) into keypoints and descriptors, shared by XFeatExtractor and SuperPointExtractor.
//
// Such a network sees the image as a grid of 8x8-pixel cells. For every cell it gives 65 logits:
// one per pixel of the cell (channel k = 8 * row_in_cell + col_in_cell) plus a "dustbin" (no
// keypoint in this cell). A softmax over the 65 channels, dropping the dustbin and moving the 64
// remaining channels back to their pixels (depth-to-space) gives a full-resolution heatmap. The
// descriptor map (and XFeat's reliability map) has one vector per cell.
//
// Coordinates: network-input pixels, the centre of the top-left pixel at (0, 0) (feature_set.h).
// Cell (i, j) of a map of stride s covers pixels [s*j, s*j + s) x [s*i, s*i + s), whose centre
// is pixel (s*j + (s-1)/2, s*i + (s-1)/2). Hence pixel p lies at map coordinate
//     u = (p + 0.5) / s - 0.5,
// the convention of cv::resize and of grid_sample(align_corners=False) on the pixel grid. Maps
// are sampled bilinearly at u, clamped to the map (the border cells extend to the image border).
// XFeat's authors map p to (p / (W - 1)) * W/s - 0.5 (W the input width), within 1/16 cell of
// the above. MagicLeap's SuperPoint demo maps p to p * (W/s - 1) / W (grid_sample with
// align_corners=True on a [0, W] range): equal at the image centre, but off by up to half a cell
// towards the borders, i.e. its descriptors are sampled towards the image centre.

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace superdyna::features {

/// A read-only view of one batch item of an NCHW float tensor: `channels` maps of rows x cols,
/// row-major.
struct DenseMap {
  const float* data = nullptr;
  int channels = 0;
  int rows = 0;
  int cols = 0;

  float at(int channel, int row, int col) const {
    return data[(static_cast<std::size_t>(channel) * rows + row) * cols + col];
  }
};

/// A keypoint candidate on the network-input pixel grid.
struct ScoredPixel {
  int x = 0;
  int y = 0;
  float score = 0.0f;
};

/// The full-resolution keypoint heatmap (CV_32FC1, rows*cell x cols*cell) of cell logits with
/// cell*cell + 1 channels (the last one is the dustbin): softmax over the channels of each cell,
/// dustbin dropped, depth-to-space. Throws InputError when the channel count is not
/// cell*cell + 1.
/// With min_heat > 0 the softmax is skipped in cells where no pixel can exceed min_heat (judged
/// from the largest pixel logit against the dustbin logit, with a safety margin); their heat is
/// left at 0. Pixels above min_heat keep their exact heat, so localMaxima(..., threshold) with
/// threshold >= min_heat finds the same maxima with the same scores (a pixel at or below the
/// threshold never decides whether a pixel above it is a maximum).
cv::Mat cellLogitsToHeatmap(const DenseMap& logits, int cell = 8, float min_heat = 0.0f);

/// Pixels whose heat equals the maximum of their window x window neighbourhood (pixels outside
/// the heatmap ignored, as a max-pool with -inf padding) and exceeds `threshold` (strictly):
/// XFeat's non-maximum suppression. Row-major order.
std::vector<ScoredPixel> localMaxima(const cv::Mat& heatmap, int window, float threshold);

/// Pixels with heat >= `threshold`, row-major order (SuperPoint's confidence threshold).
std::vector<ScoredPixel> pixelsAtLeast(const cv::Mat& heatmap, float threshold);

/// Orders by score, highest first; ties by row, then column (deterministic).
void sortByScore(std::vector<ScoredPixel>& points);

/// MagicLeap's greedy non-maximum suppression: in order of decreasing score (sortByScore), a
/// candidate is kept unless an already kept one lies within `radius` pixels in both x and y
/// (a (2r+1) x (2r+1) square). Returns the kept candidates in score order. `size` bounds the
/// pixel coordinates (else InputError). radius 0 keeps everything.
std::vector<ScoredPixel> suppressNonMaxima(std::vector<ScoredPixel> candidates, int radius,
                                           cv::Size size);

/// The points at least `border` pixels inside the rectangle [0, valid.width) x [0, valid.height)
/// (x >= border, x < width - border, same for y); order kept.
std::vector<ScoredPixel> keepInside(const std::vector<ScoredPixel>& points, int border,
                                    cv::Size valid);

/// The `k` best points, ordered by sortByScore. With grid_cell_px > 0 the image is divided into
/// square cells of that side and the choice is spread over them: every point gets its rank
/// within its cell (0 = best there), and points are taken by increasing rank, within a rank by
/// score (so every cell's best point comes before any cell's second best). k <= 0 keeps all.
std::vector<ScoredPixel> selectTopK(std::vector<ScoredPixel> points, int k, int grid_cell_px = 0);

/// Sub-pixel positions of local maxima of `heatmap` (CV_32FC1): each point moves to the
/// heat-weighted centroid (soft-argmax) of the (2 radius + 1)^2 window around it, clipped to
/// the heatmap; the weights are the heat above the window's minimum, so a flat surround does not
/// pull the peak towards the window centre. radius 0 returns the integer positions.
/// Throws OptionError for radius < 0.
std::vector<Eigen::Vector2d> refineSubpixel(const cv::Mat& heatmap,
                                            const std::vector<ScoredPixel>& points, int radius);

/// Sub-pixel positions of local maxima of `scores` (CV_32FC1) by ALIKE's soft-argmax: the mean
/// position over the (2 radius + 1)^2 window around each point, clipped to the map, weighted by
/// exp((score - window maximum) / temperature). Throws OptionError for radius < 0 or
/// temperature <= 0.
std::vector<Eigen::Vector2d> refineSoftArgmax(const cv::Mat& scores,
                                              const std::vector<ScoredPixel>& points, int radius,
                                              float temperature);

/// Map coordinate (u = column, v = row) of a pixel on a map of stride `stride` (file comment).
Eigen::Vector2d pixelToMap(const Eigen::Vector2d& pixel, int stride);

/// Bilinear interpolation of one channel at map coordinate (u, v), clamped to the map.
float sampleBilinear(const DenseMap& map, int channel, double u, double v);

/// One row per pixel (CV_32FC1, map.channels columns): the descriptor map sampled bilinearly
/// at pixelToMap(pixel, stride), then L2-normalised (a zero vector stays zero).
cv::Mat sampleDescriptors(const DenseMap& map, const std::vector<Eigen::Vector2d>& pixels,
                          int stride);

/// The map with each cell's vector L2-normalised (XFeat normalises its dense descriptors
/// before sampling them). Returns the values; view them with the same channels/rows/cols.
std::vector<float> normalizeCells(const DenseMap& map);

/// How an image is brought to a size the network accepts (sides multiples of some number).
enum class FitMode {
  kPad,     ///< Pad right and bottom by reflection (cv::BORDER_REFLECT_101); pixels unchanged.
  kResize,  ///< Resize (bilinear) to the sides rounded down to the multiple (XFeat's authors).
};

/// Where an image of size `original` goes in the network input and back.
struct ImageFit {
  FitMode mode = FitMode::kPad;
  cv::Size original;
  /// The image as the network sees it before padding: `original` scaled by the input scale
  /// (planFit), or the whole network input when resizing.
  cv::Size content;
  cv::Size network;  ///< Network input size, sides multiples of the required number.

  /// Network-input region holding image content: [0, width) x [0, height).
  cv::Size valid() const { return content; }
  /// Original-image pixels per network-input pixel, per axis (1 when padding an unscaled image).
  Eigen::Array2d pixelScale() const;
  /// Original-image pixel of a network-input pixel: pixel centres mapped onto pixel centres,
  /// (p + 0.5) * pixelScale() - 0.5 (the identity when padding an unscaled image).
  Eigen::Vector2d toOriginal(const Eigen::Vector2d& network_pixel) const;
};

/// Throws OptionError naming `key` unless 0 < scale <= 1 (an input scale of planFit).
void checkInputScale(double scale, const std::string& key = "input_scale");

/// The fit of an image of size `original` for sides that must be multiples of `multiple`:
/// the image is first scaled by `scale` (in (0, 1]; sides rounded to the nearest pixel), then
/// padded (sides rounded up) or resized (rounded down, at least `multiple`). Throws OptionError
/// when multiple < 1 or scale is outside (0, 1], InputError for an empty size.
ImageFit planFit(cv::Size original, int multiple, FitMode mode, double scale = 1.0);

/// The 8-bit image brought to fit.network as `fit` says.
cv::Mat applyFit(const cv::Mat& gray, const ImageFit& fit);

}  // namespace superdyna::features
