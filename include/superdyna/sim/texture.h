#pragma once
// Grayscale surface textures for the synthetic renderer. A texture is an image laid on a surface
// with a physical texel size, so that the renderer can look it up in metres and pick the detail
// level that matches a pixel's footprint (trilinear mipmapping: no aliasing, no shimmering).
//
// Image convention: column index grows with the texture coordinate u, row index with v; texel
// (col, row) covers [col, col + 1) x [row, row + 1) texels, its centre at (col + 0.5, row + 0.5).
// Coordinates outside the image wrap around (the texture tiles the plane), so every lookup is
// defined.

#include <Eigen/Core>
#include <cstdint>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace superdyna::sim {

/// What a procedural texture looks like. Layouts that have an up and a down (facades, rooms,
/// vehicles, people) put the top of the object at row 0, as in a photograph: a quad that shows
/// them upright has its edge_v pointing down.
enum class TextureStyle {
  kGround,      ///< Asphalt: aggregate, patches, cracks, stains, lane and parking markings.
  kFacade,      ///< Building wall: bricks / blocks / panels / plaster, window grids, shops, signs.
  kIndoor,      ///< Room wall: paint, posters, frames, doors, shelves of books, whiteboards.
  kVehicle,     ///< Car bodies side by side: panels, glass, wheels, lights, plates, dirt.
  kPedestrian,  ///< Clothing: stripes, checks, prints, logos, seams, pockets; faces and hair.
};
std::string toString(TextureStyle style);

/// Parameters of Texture::procedural().
struct ProceduralTextureOptions {
  int width = 1024;        ///< Texels along u, in [1, 16384].
  int height = 1024;       ///< Texels along v, in [1, 16384].
  double texel_m = 0.01;   ///< Size of one texel on the surface [m], > 0.
  std::uint64_t seed = 1;  ///< Different seeds give unrelated textures.
  TextureStyle style = TextureStyle::kGround;

  /// Throws OptionError naming the first invalid field.
  void validate() const;
};

/// A grayscale texture with a mipmap pyramid (level 0 is the full image, each next level halves
/// both sizes by 2x2 averaging, down to 1x1). Copies share the immutable pixel data.
class Texture {
 public:
  /// A 1x1 mid-gray (128) texture with 1 m texels: valid, featureless.
  Texture();

  /// Wraps an image as a texture (copied). CV_8UC1 is used as is; 3- and 4-channel images are
  /// converted to gray (BGR order); CV_16U is scaled by 1/256 and floating-point images are
  /// taken as gray levels 0..255 (saturated). Throws OptionError when the image is empty or
  /// texel_m is not positive.
  static Texture fromImage(const cv::Mat& image, double texel_m);

  /// A constant texture of the given gray level [0, 255] (rounded, saturated).
  static Texture uniform(double gray_level);

  /// A seeded, natural-looking multi-scale texture of the given style: fractal noise plus many
  /// high-contrast structures (edges and corners at several scales), contrast spread over the
  /// 8-bit range. Deterministic for given options; about 0.2 s per 10^7 texels.
  static Texture procedural(const ProceduralTextureOptions& options);

  /// A width x height mosaic of randomly placed, scaled and flipped crops of real photographs
  /// (any type fromImage() accepts), for texturing with a folder of images. Deterministic for a
  /// given seed and photo list. Throws OptionError when there is no usable photo or a size or
  /// texel_m is not positive.
  static Texture fromPhotos(const std::vector<cv::Mat>& photos, int width, int height,
                            double texel_m, std::uint64_t seed);

  /// This texture with its contrast scaled by `factor` about its mean gray level: level 0 becomes
  /// mean + factor * (gray - mean), rounded and saturated, and the mipmap is rebuilt. `factor` in
  /// (0, 4] (else OptionError); 1 returns the texture unchanged.
  Texture withContrast(double factor) const;

  /// Gray level [0, 255] at surface coordinates uv_m [m] (u along the image columns), averaged
  /// over a footprint of footprint_m [m] (the size of one rendered pixel on the surface):
  /// bilinear interpolation in the two mipmap levels around log2(footprint_m / texel_m), blended
  /// linearly. Footprints at or below one texel give plain bilinear interpolation in level 0.
  float sample(const Eigen::Vector2d& uv_m, double footprint_m) const;

  int width() const { return levels_.front().cols; }      ///< Texels along u (level 0).
  int height() const { return levels_.front().rows; }     ///< Texels along v (level 0).
  double texelSizeM() const { return texel_m_; }          ///< Texel size of level 0 [m].
  double widthM() const { return width() * texel_m_; }    ///< Extent along u [m].
  double heightM() const { return height() * texel_m_; }  ///< Extent along v [m].
  int levelCount() const { return static_cast<int>(levels_.size()); }
  /// Mipmap level `level` (CV_8UC1, shared data: do not modify).
  const cv::Mat& level(int level) const { return levels_.at(static_cast<std::size_t>(level)); }
  /// Level 0 (CV_8UC1, shared data: do not modify).
  const cv::Mat& image() const { return levels_.front(); }

 private:
  Texture(cv::Mat image, double texel_m);
  /// Bilinear lookup in one level, wrapping around the borders.
  float bilinear(std::size_t level, double u_m, double v_m) const;

  std::vector<cv::Mat> levels_;
  /// Texels per metre of each level along u and v: each level spans the same surface, so odd
  /// sizes give slightly non-power-of-two texel sizes and the wrap-around stays seamless.
  std::vector<Eigen::Vector2d> level_texels_per_m_;
  double texel_m_ = 1.0;
};

}  // namespace superdyna::sim
