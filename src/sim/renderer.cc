#include "superdyna/sim/renderer.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <limits>
#include <thread>

#include "superdyna/core/error.h"
#include "superdyna/sim/hash.h"

namespace superdyna::sim {

namespace {

constexpr double kInf = std::numeric_limits<double>::infinity();
/// Slack of the inside-quad test in edge units: closes cracks along edges that two quads share
/// (each computes the edge with its own rounding), far below a pixel.
constexpr double kInsideTolerance = 1e-9;
/// Pixels added around the projected outline of a quad: the outline is sampled at most every
/// kMaxEdgeStepPx pixels, and a distorted edge bows by far less than this between samples.
constexpr int kBoundsMarginPx = 2;
constexpr double kMaxEdgeStepPx = 4.0;
constexpr int kMaxEdgeSubdivisions = 12;
/// Rows per unit of work: small enough to interleave sky and ground between threads, large
/// enough that one quad's rows stay in cache.
constexpr int kRowsPerChunk = 16;
/// Incidence cosine below which the footprint stops growing (grazing surfaces stay sharp-ish).
constexpr double kMinIncidenceCosine = 0.1;
/// Spacing of the pixels whose motion over the exposure sets the automatic sub-frame count.
constexpr int kMotionGridPx = 8;

/// Runs fn(row_begin, row_end) on chunks of kRowsPerChunk rows; chunk k goes to thread
/// k % threads. Each pixel is computed by exactly one call, so the result does not depend on the
/// number of threads. `fn` must not throw.
template <typename Fn>
void forEachRowChunk(int rows, int threads, const Fn& fn) {
  const int chunks = (rows + kRowsPerChunk - 1) / kRowsPerChunk;
  threads = std::clamp(threads, 1, std::max(1, chunks));
  const auto work = [&](int first_chunk) {
    for (int chunk = first_chunk; chunk < chunks; chunk += threads) {
      fn(chunk * kRowsPerChunk, std::min(rows, (chunk + 1) * kRowsPerChunk));
    }
  };
  std::vector<std::thread> workers;
  for (int t = 1; t < threads; ++t) {
    workers.emplace_back(work, t);
  }
  work(0);
  for (std::thread& worker : workers) {
    worker.join();
  }
}

int defaultThreadCount() {
  return static_cast<int>(std::clamp(std::thread::hardware_concurrency(), 1u, 8u));
}

/// Standard normal quantiles at the centres of 2^16 equal-probability bins: 16 random bits
/// index a normal number (truncated at 4.3 sigma, plenty for sensor noise) for the cost of a
/// table lookup instead of a logarithm and a sine per pixel.
const std::vector<float>& normalQuantiles() {
  static const std::vector<float> table = [] {
    constexpr int kSize = 1 << 16;
    std::vector<float> quantiles(kSize);
    double z = 0.0;  // upper half by Newton's method from the previous quantile, mirrored
    for (int k = kSize / 2; k < kSize; ++k) {
      const double p = (k + 0.5) / kSize;
      for (int iteration = 0; iteration < 50; ++iteration) {
        const double cdf = 0.5 * std::erfc(-z / std::sqrt(2.0));
        const double step = (cdf - p) / (std::exp(-0.5 * z * z) / std::sqrt(2.0 * M_PI));
        z -= step;
        if (std::abs(step) < 1e-9) break;
      }
      quantiles[static_cast<std::size_t>(k)] = static_cast<float>(z);
      quantiles[static_cast<std::size_t>(kSize - 1 - k)] = static_cast<float>(-z);
    }
    return quantiles;
  }();
  return table;
}

/// The automatic sub-frame count: consecutive sub-frames at most step_px apart, odd so that the
/// middle one is the central frame (rendered anyway), at most max_samples.
int automaticBlurSamples(double motion_px, double step_px, int max_samples) {
  const double needed = std::ceil(motion_px / step_px);
  int samples = needed >= max_samples ? max_samples : std::max(1, static_cast<int>(needed));
  if (samples % 2 == 0 && samples < max_samples) ++samples;
  return samples;
}

void requireFinite(double value, double min_value, const char* name) {
  if (!std::isfinite(value) || value < min_value) {
    throw OptionError(name, fmt::format("must be finite and >= {}, got {}", min_value, value));
  }
}

/// The part of a convex polygon (camera frame) in front of the plane z = near_m
/// (Sutherland-Hodgman against one plane).
std::vector<Eigen::Vector3d> clipToNearPlane(const std::vector<Eigen::Vector3d>& polygon,
                                             double near_m) {
  std::vector<Eigen::Vector3d> clipped;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector3d& a = polygon[i];
    const Eigen::Vector3d& b = polygon[(i + 1) % polygon.size()];
    const bool a_in = a.z() >= near_m, b_in = b.z() >= near_m;
    if (a_in) clipped.push_back(a);
    if (a_in != b_in) clipped.push_back(a + (near_m - a.z()) / (b.z() - a.z()) * (b - a));
  }
  return clipped;
}

/// Axis-aligned bounds of pixel positions.
struct PixelBox {
  double min_x = kInf, min_y = kInf, max_x = -kInf, max_y = -kInf;

  void add(const Eigen::Vector2d& p) {
    min_x = std::min(min_x, p.x());
    min_y = std::min(min_y, p.y());
    max_x = std::max(max_x, p.x());
    max_y = std::max(max_y, p.y());
  }
  /// Integer pixel rectangle with a margin, clipped to the image; empty when outside.
  cv::Rect toRect(int margin, int width, int height) const {
    if (!(min_x <= max_x) || !(min_y <= max_y)) return {};
    const double x0 = std::max(0.0, std::floor(min_x) - margin);
    const double y0 = std::max(0.0, std::floor(min_y) - margin);
    const double x1 = std::min(width - 1.0, std::ceil(max_x) + margin);
    const double y1 = std::min(height - 1.0, std::ceil(max_y) + margin);
    if (x1 < x0 || y1 < y0) return {};
    return {static_cast<int>(x0), static_cast<int>(y0), static_cast<int>(x1 - x0) + 1,
            static_cast<int>(y1 - y0) + 1};
  }
};

/// Unit bearing of every pixel centre (row-major), zero where the camera cannot unproject.
std::vector<Eigen::Vector3d> unprojectPixelCentres(const CameraModel& camera) {
  const int width = camera.width();
  std::vector<Eigen::Vector3d> bearings(static_cast<std::size_t>(width) * camera.height(),
                                        Eigen::Vector3d::Zero());
  forEachRowChunk(camera.height(), defaultThreadCount(), [&](int row_begin, int row_end) {
    for (int r = row_begin; r < row_end; ++r) {
      for (int c = 0; c < width; ++c) {
        const auto bearing = camera.unproject(Eigen::Vector2d(c, r));
        if (bearing && bearing->allFinite()) {
          bearings[static_cast<std::size_t>(r) * width + c] = bearing->normalized();
        }
      }
    }
  });
  return bearings;
}

/// Angular size of each pixel [rad]: the larger angle to the next bearing along the row and
/// the column (1 / focal length where a neighbour is missing).
std::vector<float> pixelAngles(const std::vector<Eigen::Vector3d>& bearings,
                               const CameraModel& camera) {
  const int width = camera.width(), height = camera.height();
  std::vector<float> angles(bearings.size(),
                            static_cast<float>(1.0 / std::max(camera.fx(), camera.fy())));
  const auto at = [&](int r, int c) -> const Eigen::Vector3d& {
    return bearings[static_cast<std::size_t>(r) * width + c];
  };
  for (int r = 0; r < height; ++r) {
    const int r_next = r + 1 < height ? r + 1 : std::max(0, r - 1);
    for (int c = 0; c < width; ++c) {
      const int c_next = c + 1 < width ? c + 1 : std::max(0, c - 1);
      const Eigen::Vector3d &d = at(r, c), &d_x = at(r, c_next), &d_y = at(r_next, c);
      if (d.isZero() || d_x.isZero() || d_y.isZero()) continue;
      const double angle = std::max((d - d_x).norm(), (d - d_y).norm());
      if (angle > 0.0) angles[static_cast<std::size_t>(r) * width + c] = static_cast<float>(angle);
    }
  }
  return angles;
}

/// Largest radius in the normalised image plane (x/z, y/z) of a bearing in front of the camera.
double maxNormalizedRadius(const std::vector<Eigen::Vector3d>& bearings) {
  double max_radius = 0.0;
  for (const Eigen::Vector3d& d : bearings) {
    if (d.z() > 1e-9) max_radius = std::max(max_radius, d.head<2>().norm() / d.z());
  }
  return max_radius;
}

}  // namespace

/// A scene quad in the camera frame, set up for ray casting. With the plane normal
/// n = edge_u x edge_v, a ray s * d (unit d) meets the plane at s = (n . origin) / (n . d), and
/// the hit p has edge coordinates a = dual_u . p - origin_u, b = dual_v . p - origin_v.
struct Renderer::CameraQuad {
  Eigen::Vector3d normal;
  double normal_dot_origin = 0.0;
  double inverse_normal_norm = 0.0;
  Eigen::Vector3d dual_u, dual_v;
  double origin_u = 0.0, origin_v = 0.0;
  double length_u_m = 0.0, length_v_m = 0.0;
  Eigen::Vector2d texture_offset_m;
  const Texture* texture = nullptr;
  std::uint16_t instance_id = 0;
  std::size_t object = 0;  ///< Index of the quad's object in the scene.
  cv::Rect box;            ///< Pixels whose rays may hit the quad.
};

/// Result of the z-buffer pass: per pixel, the nearest hit's ray distance and quad.
struct Renderer::Visibility {
  std::vector<double> ray_distance;  ///< Along the unit bearing [m]; +inf where nothing is hit.
  std::vector<std::int32_t> quad;    ///< Index into the frame's quads; -1 where nothing is hit.
};

/// Per-frame working memory (about 25 bytes per pixel), kept per calling thread and reused:
/// fresh buffers every frame would cost more in page faults than the ray casting itself.
struct Renderer::FrameBuffers {
  Visibility visibility;
  std::vector<float> central;    ///< Radiance at t_ns.
  std::vector<float> sub_frame;  ///< Radiance of one motion-blur sub-frame.
  std::vector<float> blurred;    ///< Mean radiance over the exposure.

  void resize(std::size_t pixels) {
    visibility.ray_distance.resize(pixels);
    visibility.quad.resize(pixels);
    central.resize(pixels);
  }
};

void RenderOptions::validate() const {
  requireFinite(background_gray, -kInf, "background_gray");
  requireFinite(gain, 0.0, "gain");
  requireFinite(noise_sigma, 0.0, "noise_sigma");
  requireFinite(exposure_s, 0.0, "exposure_s");
  if (!(near_m > 0.0) || !std::isfinite(near_m)) throw OptionError("near_m", "must be > 0");
  if (blur_samples < 0 || blur_samples > 256) {
    throw OptionError("blur_samples",
                      fmt::format("must be in [0, 256] (0 = automatic), got {}", blur_samples));
  }
  if (!(blur_step_px > 0.0) || !std::isfinite(blur_step_px)) {
    throw OptionError("blur_step_px", fmt::format("must be > 0, got {}", blur_step_px));
  }
  if (max_blur_samples < 1 || max_blur_samples > 256) {
    throw OptionError("max_blur_samples",
                      fmt::format("must be in [1, 256], got {}", max_blur_samples));
  }
  if (threads < 1 || threads > 256) {
    throw OptionError("threads", fmt::format("must be in [1, 256], got {}", threads));
  }
}

Renderer::Renderer(const CameraModel& camera) : camera_(camera) {
  if (camera.width() <= 0 || camera.height() <= 0) throw OptionError("camera", "has no pixels");
  bearings_ = unprojectPixelCentres(camera);
  pixel_angle_rad_ = pixelAngles(bearings_, camera);
  // The equidistant model goes through atan(radius) and takes any radius; polynomial
  // radial-tangential models can fold back beyond the calibrated field, so bounding points are
  // pulled in to just outside the field of the image.
  max_normalized_radius_ = camera.distortionModel() == DistortionModel::kEquidistant
                               ? kInf
                               : 1.05 * maxNormalizedRadius(bearings_) + 1e-3;
}

Eigen::Vector2d Renderer::pixelOfNormalized(const Eigen::Vector2d& normalized) const {
  Eigen::Vector2d n = normalized;
  const double radius = n.norm();
  if (radius > max_normalized_radius_) n *= max_normalized_radius_ / radius;
  const Eigen::Vector2d d = camera_.distort(n);
  return {camera_.fx() * d.x() + camera_.cx(), camera_.fy() * d.y() + camera_.cy()};
}

cv::Rect Renderer::pixelBounds(const std::vector<Eigen::Vector3d>& corners_c, double near_m) const {
  // Perspective maps each 3D edge to a straight segment of the normalised plane; distortion then
  // bends it, so each segment is sampled until consecutive pixels are at most kMaxEdgeStepPx
  // apart. Points pulled onto the field's rim keep the bounds conservative: a ray of an image
  // pixel lies inside the rim, and the rim part of the clipped outline is what they cover.
  const std::vector<Eigen::Vector3d> polygon = clipToNearPlane(corners_c, near_m);
  if (polygon.size() < 3) return {};
  PixelBox box;
  for (std::size_t i = 0; i < polygon.size(); ++i) {
    const Eigen::Vector3d& a = polygon[i];
    const Eigen::Vector3d& b = polygon[(i + 1) % polygon.size()];
    const Eigen::Vector2d n_a = a.head<2>() / a.z(), n_b = b.head<2>() / b.z();
    struct Piece {
      double t0, t1;
      Eigen::Vector2d p0, p1;
      int depth;
    };
    const auto at = [&](double t) { return pixelOfNormalized(n_a + t * (n_b - n_a)); };
    std::vector<Piece> stack;
    constexpr int kInitialPieces = 8;
    Eigen::Vector2d previous = at(0.0);
    box.add(previous);
    for (int k = 1; k <= kInitialPieces; ++k) {
      const double t = static_cast<double>(k) / kInitialPieces;
      const Eigen::Vector2d p = at(t);
      box.add(p);
      stack.push_back({t - 1.0 / kInitialPieces, t, previous, p, 0});
      previous = p;
    }
    while (!stack.empty()) {
      const Piece piece = stack.back();
      stack.pop_back();
      if (piece.depth >= kMaxEdgeSubdivisions || (piece.p1 - piece.p0).norm() <= kMaxEdgeStepPx) {
        continue;
      }
      const double t_mid = 0.5 * (piece.t0 + piece.t1);
      const Eigen::Vector2d mid = at(t_mid);
      box.add(mid);
      stack.push_back({piece.t0, t_mid, piece.p0, mid, piece.depth + 1});
      stack.push_back({t_mid, piece.t1, mid, piece.p1, piece.depth + 1});
    }
  }
  return box.toRect(kBoundsMarginPx, camera_.width(), camera_.height());
}

std::vector<Renderer::CameraQuad> Renderer::prepareQuads(const Scene& scene, const SE3d& T_w_c,
                                                         TimeNs t_ns, double near_m) const {
  std::vector<CameraQuad> quads;
  const SE3d T_c_w = T_w_c.inverse();
  for (std::size_t o = 0; o < scene.objects.size(); ++o) {
    const SceneObject& object = scene.objects[o];
    SE3d T_w_o;
    if (object.T_w_o) {
      const std::optional<SE3d> pose = object.T_w_o(t_ns);
      if (!pose) continue;  // not in the world at this time
      T_w_o = *pose;
    }
    const SE3d T_c_o = T_c_w * T_w_o;
    const Eigen::Matrix3d R_c_o = T_c_o.rotation();
    for (std::size_t k = 0; k < object.quads.size(); ++k) {
      const Quad& quad = object.quads[k];
      if (quad.texture < 0 || static_cast<std::size_t>(quad.texture) >= scene.textures.size()) {
        throw OptionError("scene",
                          fmt::format("object {} quad {} uses texture {}, but there are {}", o, k,
                                      quad.texture, scene.textures.size()));
      }
      const Eigen::Vector3d origin_c = T_c_o * quad.origin;
      const Eigen::Vector3d edge_u_c = R_c_o * quad.edge_u, edge_v_c = R_c_o * quad.edge_v;
      const std::vector<Eigen::Vector3d> corners_c = {
          origin_c, origin_c + edge_u_c, origin_c + edge_u_c + edge_v_c, origin_c + edge_v_c};
      if (std::all_of(corners_c.begin(), corners_c.end(),
                      [&](const Eigen::Vector3d& p) { return p.z() < near_m; })) {
        continue;  // behind the camera
      }
      const Eigen::Vector3d normal = edge_u_c.cross(edge_v_c);
      const double normal_sq = normal.squaredNorm();
      if (!(normal_sq > 1e-24)) continue;  // degenerate: no area
      const cv::Rect box = pixelBounds(corners_c, near_m);
      if (box.empty()) continue;
      CameraQuad q;
      q.normal = normal;
      q.normal_dot_origin = normal.dot(origin_c);
      q.inverse_normal_norm = 1.0 / std::sqrt(normal_sq);
      q.dual_u = edge_v_c.cross(normal) / normal_sq;
      q.dual_v = normal.cross(edge_u_c) / normal_sq;
      q.origin_u = q.dual_u.dot(origin_c);
      q.origin_v = q.dual_v.dot(origin_c);
      q.length_u_m = quad.edge_u.norm();
      q.length_v_m = quad.edge_v.norm();
      q.texture_offset_m = quad.texture_offset_m;
      q.texture = &scene.textures[static_cast<std::size_t>(quad.texture)];
      q.instance_id = object.instance_id;
      q.object = o;
      q.box = box;
      quads.push_back(q);
    }
  }
  return quads;
}

void Renderer::castRays(const std::vector<CameraQuad>& quads, const RenderOptions& options,
                        Visibility& visibility) const {
  const int width = camera_.width();
  const double near_m = options.near_m;
  forEachRowChunk(camera_.height(), options.threads, [&](int row_begin, int row_end) {
    // Each chunk clears its own rows, so the (page-touching) reset is shared out too.
    const auto chunk_begin = static_cast<std::ptrdiff_t>(row_begin) * width;
    const auto chunk_end = static_cast<std::ptrdiff_t>(row_end) * width;
    std::fill(visibility.ray_distance.begin() + chunk_begin,
              visibility.ray_distance.begin() + chunk_end, kInf);
    std::fill(visibility.quad.begin() + chunk_begin, visibility.quad.begin() + chunk_end, -1);
    for (std::size_t qi = 0; qi < quads.size(); ++qi) {
      const CameraQuad& q = quads[qi];
      const int r_end = std::min(row_end, q.box.y + q.box.height);
      for (int r = std::max(row_begin, q.box.y); r < r_end; ++r) {
        const std::size_t row_start = static_cast<std::size_t>(r) * width;
        for (int c = q.box.x; c < q.box.x + q.box.width; ++c) {
          const std::size_t i = row_start + static_cast<std::size_t>(c);
          const Eigen::Vector3d& d = bearings_[i];
          const double n_dot_d = q.normal.dot(d);
          if (n_dot_d == 0.0) continue;  // parallel ray, or a pixel without bearing
          const double s = q.normal_dot_origin / n_dot_d;
          if (!(s < visibility.ray_distance[i]) || !(s * d.z() >= near_m)) continue;
          const double a = s * q.dual_u.dot(d) - q.origin_u;
          if (a < -kInsideTolerance || a > 1.0 + kInsideTolerance) continue;
          const double b = s * q.dual_v.dot(d) - q.origin_v;
          if (b < -kInsideTolerance || b > 1.0 + kInsideTolerance) continue;
          visibility.ray_distance[i] = s;
          visibility.quad[i] = static_cast<std::int32_t>(qi);
        }
      }
    }
  });
}

void Renderer::shade(const std::vector<CameraQuad>& quads, const Visibility& visibility,
                     const RenderOptions& options, float* radiance) const {
  const int width = camera_.width();
  const auto background = static_cast<float>(options.background_gray);
  forEachRowChunk(camera_.height(), options.threads, [&](int row_begin, int row_end) {
    const auto end = static_cast<std::size_t>(row_end) * width;
    for (auto i = static_cast<std::size_t>(row_begin) * width; i < end; ++i) {
      const std::int32_t qi = visibility.quad[i];
      if (qi < 0) {
        radiance[i] = background;
        continue;
      }
      const CameraQuad& q = quads[static_cast<std::size_t>(qi)];
      const Eigen::Vector3d& d = bearings_[i];
      const double s = visibility.ray_distance[i];
      const double a = s * q.dual_u.dot(d) - q.origin_u;
      const double b = s * q.dual_v.dot(d) - q.origin_v;
      const Eigen::Vector2d uv_m =
          q.texture_offset_m + Eigen::Vector2d(a * q.length_u_m, b * q.length_v_m);
      // The pixel's cone widens with distance and stretches over a slanted surface.
      const double cos_incidence = std::abs(q.normal.dot(d)) * q.inverse_normal_norm;
      const double footprint_m =
          s * pixel_angle_rad_[i] / std::max(cos_incidence, kMinIncidenceCosine);
      radiance[i] = q.texture->sample(uv_m, footprint_m);
    }
  });
}

void Renderer::writeInstanceAndDepth(const std::vector<CameraQuad>& quads,
                                     const Visibility& visibility, const RenderOptions& options,
                                     RenderResult& result) const {
  const int width = camera_.width();
  result.instance.create(camera_.height(), width, CV_16UC1);
  result.depth.create(camera_.height(), width, CV_32FC1);
  forEachRowChunk(camera_.height(), options.threads, [&](int row_begin, int row_end) {
    for (int r = row_begin; r < row_end; ++r) {
      auto* instance_row = result.instance.ptr<std::uint16_t>(r);
      auto* depth_row = result.depth.ptr<float>(r);
      for (int c = 0; c < width; ++c) {
        const std::size_t i = static_cast<std::size_t>(r) * width + c;
        const std::int32_t qi = visibility.quad[i];
        instance_row[c] = qi < 0 ? 0 : quads[static_cast<std::size_t>(qi)].instance_id;
        depth_row[c] = qi < 0 ? std::numeric_limits<float>::infinity()
                              : static_cast<float>(visibility.ray_distance[i] * bearings_[i].z());
      }
    }
  });
}

std::vector<Renderer::CameraQuad> Renderer::renderRadiance(const Scene& scene, const SE3d& T_w_c,
                                                           TimeNs t_ns,
                                                           const RenderOptions& options,
                                                           Visibility& visibility, float* radiance,
                                                           RenderResult* central) const {
  std::vector<CameraQuad> quads = prepareQuads(scene, T_w_c, t_ns, options.near_m);
  castRays(quads, options, visibility);
  shade(quads, visibility, options, radiance);
  if (central != nullptr) writeInstanceAndDepth(quads, visibility, options, *central);
  return quads;
}

double Renderer::exposureMotionPx(const Scene& scene, const std::function<SE3d(TimeNs)>& T_w_c_at,
                                  TimeNs t_ns, double exposure_s,
                                  const std::vector<CameraQuad>& quads,
                                  const Visibility& visibility) const {
  const TimeNs t_begin = t_ns - secondsToNs(0.5 * exposure_s);
  const TimeNs t_end = t_ns + secondsToNs(0.5 * exposure_s);
  const SE3d T_w_c = T_w_c_at(t_ns);
  const SE3d T_c_w_begin = T_w_c_at(t_begin).inverse(), T_c_w_end = T_w_c_at(t_end).inverse();
  // How each object seen at t_ns moves a world point over the exposure: p(t') = T_w_o(t') *
  // T_w_o(t)^-1 * p(t). Identity for the static world and while an object is out of the world.
  struct ObjectMotion {
    bool known = false;
    SE3d begin, end;
  };
  std::vector<ObjectMotion> motions(scene.objects.size());
  const auto motionOf = [&](std::size_t o) -> const ObjectMotion& {
    ObjectMotion& motion = motions[o];
    if (motion.known) return motion;
    motion.known = true;
    const PoseTrack& track = scene.objects[o].T_w_o;
    if (!track) return motion;
    const std::optional<SE3d> now = track(t_ns), begin = track(t_begin), end = track(t_end);
    if (!now || !begin || !end) return motion;
    motion.begin = *begin * now->inverse();
    motion.end = *end * now->inverse();
    return motion;
  };
  const int width = camera_.width();
  double max_motion = 0.0;
  for (int r = kMotionGridPx / 2; r < camera_.height(); r += kMotionGridPx) {
    for (int c = kMotionGridPx / 2; c < width; c += kMotionGridPx) {
      const std::size_t i = static_cast<std::size_t>(r) * width + c;
      const std::int32_t qi = visibility.quad[i];
      if (qi < 0) continue;
      const ObjectMotion& motion = motionOf(quads[static_cast<std::size_t>(qi)].object);
      const Eigen::Vector3d p_w = T_w_c * (visibility.ray_distance[i] * bearings_[i]);
      const auto u_begin = camera_.project(T_c_w_begin * (motion.begin * p_w));
      const auto u_end = camera_.project(T_c_w_end * (motion.end * p_w));
      if (u_begin && u_end) max_motion = std::max(max_motion, (*u_end - *u_begin).norm());
    }
  }
  return max_motion;
}

RenderResult Renderer::render(const Scene& scene, const SE3d& T_w_c, TimeNs t_ns,
                              const RenderOptions& options) const {
  return render(
      scene, [&T_w_c](TimeNs) { return T_w_c; }, t_ns, options);
}

RenderResult Renderer::render(const Scene& scene, const std::function<SE3d(TimeNs)>& T_w_c_at,
                              TimeNs t_ns, const RenderOptions& options) const {
  options.validate();
  if (!T_w_c_at) throw OptionError("T_w_c_at", "the camera pose function is empty");
  const std::size_t pixels = bearings_.size();
  thread_local FrameBuffers buffers;
  buffers.resize(pixels);
  RenderResult result;
  const std::vector<CameraQuad> central_quads = renderRadiance(
      scene, T_w_c_at(t_ns), t_ns, options, buffers.visibility, buffers.central.data(), &result);
  if (options.exposure_s > 0.0) {
    result.exposure_motion_px = exposureMotionPx(scene, T_w_c_at, t_ns, options.exposure_s,
                                                 central_quads, buffers.visibility);
  }
  result.blur_samples = options.blur_samples != 0
                            ? options.blur_samples
                            : automaticBlurSamples(result.exposure_motion_px, options.blur_step_px,
                                                   options.max_blur_samples);

  // Motion blur: sub-frames at the centres of blur_samples equal slices of the exposure. With an
  // odd count the middle one is t_ns itself and reuses the central frame.
  const float* radiance = buffers.central.data();
  if (result.blur_samples > 1) {
    buffers.blurred.assign(pixels, 0.0f);
    buffers.sub_frame.resize(pixels);
    const int samples = result.blur_samples;
    for (int k = 0; k < samples; ++k) {
      const double offset_s = options.exposure_s * ((k + 0.5) / samples - 0.5);
      const TimeNs t_k = t_ns + secondsToNs(offset_s);
      const float* source = buffers.central.data();
      if (t_k != t_ns) {
        renderRadiance(scene, T_w_c_at(t_k), t_k, options, buffers.visibility,
                       buffers.sub_frame.data(), nullptr);
        source = buffers.sub_frame.data();
      }
      for (std::size_t i = 0; i < pixels; ++i) {
        buffers.blurred[i] += source[i];
      }
    }
    for (float& value : buffers.blurred) {
      value /= static_cast<float>(samples);
    }
    radiance = buffers.blurred.data();
  }

  // Exposure gain, sensor noise, quantisation.
  const int width = camera_.width();
  result.image.create(camera_.height(), width, CV_8UC1);
  const std::uint64_t frame_key = mix64(options.seed ^ mix64(static_cast<std::uint64_t>(t_ns)));
  const auto gain = static_cast<float>(options.gain);
  const auto sigma = static_cast<float>(options.noise_sigma);
  const auto groups_per_row = static_cast<std::uint64_t>((width + 3) / 4);
  const std::vector<float>& quantiles = normalQuantiles();
  forEachRowChunk(camera_.height(), options.threads, [&](int row_begin, int row_end) {
    for (int r = row_begin; r < row_end; ++r) {
      auto* row = result.image.ptr<std::uint8_t>(r);
      const float* row_radiance = radiance + static_cast<std::size_t>(r) * width;
      std::uint64_t bits = 0;
      for (int c = 0; c < width; ++c) {
        // One hash gives the noise of 4 neighbouring pixels of a row, 16 bits each.
        if (c % 4 == 0)
          bits = mix64(frame_key + r * groups_per_row + static_cast<std::uint64_t>(c / 4));
        const float noise =
            sigma > 0.0f ? sigma * quantiles[(bits >> (16 * (c % 4))) & 0xFFFF] : 0.0f;
        const float value = gain * row_radiance[c] + noise;
        row[c] = static_cast<std::uint8_t>(std::clamp(value, 0.0f, 255.0f) + 0.5f);
      }
    }
  });
  return result;
}

}  // namespace superdyna::sim
