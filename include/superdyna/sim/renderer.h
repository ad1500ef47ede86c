#pragma once
// Ray-casting renderer for the synthetic world: a grayscale image, an instance mask and a depth
// map, all from the same per-pixel visibility decision, so the mask is exactly what the image
// shows. Each pixel casts one ray through its centre along the camera's exact (distorted) bearing;
// the nearest quad hit wins (z-buffer pass), then the winning surfaces are shaded with mipmapped
// textures (shading pass). Optional motion blur averages sub-frames over the exposure.
//
// Frames: T_w_c is the camera pose in the world (p_w = T_w_c * p_c), camera axes as in
// CameraModel (z forward, x right, y down); T_w_o(t) places each object's quads in the world.

#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <vector>

#include "superdyna/core/camera_model.h"
#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/sim/scene.h"

namespace superdyna::sim {

/// How to render one frame. The output does not depend on `threads`.
struct RenderOptions {
  double background_gray = 200.0;  ///< Radiance where no quad is hit (sky, far) [0, 255].
  double gain = 1.0;               ///< Illumination / exposure gain on all radiance, >= 0.
  double noise_sigma = 0.0;        ///< Std of additive Gaussian noise [gray levels]; 0 = off.
  std::uint64_t seed = 0;          ///< Noise seed; a frame's noise is a function of (seed, t_ns).
  /// Sub-frames averaged for motion blur: 1 = no blur, >= 2 a fixed count, 0 = automatic (the
  /// fewest that keep consecutive sub-frames at most blur_step_px apart, up to
  /// max_blur_samples).
  int blur_samples = 1;
  double exposure_s = 0.0;    ///< Time the sub-frames span, centred on t_ns [s], >= 0.
  double blur_step_px = 1.0;  ///< Automatic count: largest image motion between sub-frames.
  int max_blur_samples = 15;  ///< Automatic count: upper bound, in [1, 256].
  /// Near clipping distance along the optical axis [m], > 0. Only surfaces with z >= near_m
  /// are drawn, so a fisheye wider than 180 degrees shows the background behind the camera.
  double near_m = 0.05;
  int threads = 2;  ///< Worker threads (rows are shared out), >= 1.

  /// Throws OptionError naming the first invalid field.
  void validate() const;
};

/// One rendered frame; all images have the camera's size.
struct RenderResult {
  cv::Mat image;     ///< CV_8UC1 gray image (blurred, with noise, when the options say so).
  cv::Mat instance;  ///< CV_16UC1: instance_id of the object seen at t_ns, 0 = static or nothing.
  cv::Mat depth;     ///< CV_32FC1: z of the surface seen at t_ns [m], +inf where nothing is hit.
  int blur_samples = 1;  ///< Sub-frames the image averages (1 = sharp).
  /// Largest image motion over the exposure of the surfaces seen at t_ns (camera and agents
  /// alike), on a grid of pixels [px]; 0 without exposure.
  double exposure_motion_px = 0.0;
};

/// Camera-specific ray caster. Construction precomputes one unit bearing per pixel centre with
/// CameraModel::unproject (exact for any distortion; pixels that cannot be unprojected stay
/// background); render() is const and may be called from several threads at once.
class Renderer {
 public:
  /// Throws OptionError when the camera has no pixels.
  explicit Renderer(const CameraModel& camera);

  const CameraModel& camera() const { return camera_; }

  /// Renders the scene at time t_ns [ns] from a camera pose that is fixed during the exposure
  /// (with blur_samples > 1, only moving objects blur).
  RenderResult render(const Scene& scene, const SE3d& T_w_c, TimeNs t_ns,
                      const RenderOptions& options) const;

  /// Renders the scene at time t_ns [ns] with the camera pose given as a function of time, which
  /// is called at t_ns and, for motion blur, at the centres of blur_samples equal slices of
  /// [t_ns - exposure/2, t_ns + exposure/2] (t_ns is mid-exposure). Objects move along their own
  /// tracks meanwhile. The image averages those sub-frames; the instance mask and depth are those
  /// at t_ns. Throws OptionError for invalid options, an empty pose function or a quad whose
  /// texture index is out of range.
  RenderResult render(const Scene& scene, const std::function<SE3d(TimeNs)>& T_w_c_at, TimeNs t_ns,
                      const RenderOptions& options) const;

 private:
  struct CameraQuad;
  struct Visibility;
  struct FrameBuffers;

  std::vector<CameraQuad> prepareQuads(const Scene& scene, const SE3d& T_w_c, TimeNs t_ns,
                                       double near_m) const;
  cv::Rect pixelBounds(const std::vector<Eigen::Vector3d>& corners_c, double near_m) const;
  Eigen::Vector2d pixelOfNormalized(const Eigen::Vector2d& normalized) const;
  void castRays(const std::vector<CameraQuad>& quads, const RenderOptions& options,
                Visibility& visibility) const;
  void shade(const std::vector<CameraQuad>& quads, const Visibility& visibility,
             const RenderOptions& options, float* radiance) const;
  void writeInstanceAndDepth(const std::vector<CameraQuad>& quads, const Visibility& visibility,
                             const RenderOptions& options, RenderResult& result) const;
  /// Largest image motion over the exposure of the surfaces a grid of pixels sees at t_ns.
  double exposureMotionPx(const Scene& scene, const std::function<SE3d(TimeNs)>& T_w_c_at,
                          TimeNs t_ns, double exposure_s, const std::vector<CameraQuad>& quads,
                          const Visibility& visibility) const;
  /// Ray casts and shades one (sub-)frame; `central` also gets the mask and depth. Returns the
  /// frame's quads (what visibility.quad indexes).
  std::vector<CameraQuad> renderRadiance(const Scene& scene, const SE3d& T_w_c, TimeNs t_ns,
                                         const RenderOptions& options, Visibility& visibility,
                                         float* radiance, RenderResult* central) const;

  CameraModel camera_;
  std::vector<Eigen::Vector3d> bearings_;  ///< Unit bearing per pixel (row-major); 0 = invalid.
  std::vector<float> pixel_angle_rad_;     ///< Angular size of each pixel [rad].
  /// Normalised-plane radius beyond which edge points are pulled in before distortion when
  /// bounding a quad (radial-tangential models fold back far outside the calibrated field).
  double max_normalized_radius_ = 0.0;
};

}  // namespace superdyna::sim
