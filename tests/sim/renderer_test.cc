#include "superdyna/sim/renderer.h"

#include <gtest/gtest.h>

#include <chrono>
#include <cmath>
#include <cstdlib>
#include <cstring>
#include <filesystem>
#include <limits>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>

#include "superdyna/core/error.h"

namespace superdyna::sim {
namespace {

CameraModel pinholeCamera() {
  return CameraModel(752, 480, 460.0, 455.0, 371.3, 243.7);
}

CameraModel eurocCamera() {
  return CameraModel(752, 480, 458.654, 457.296, 367.215, 248.375,
                     DistortionModel::kRadialTangential,
                     {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05});
}

/// A wide fisheye: the image corners see 100 degrees off the axis (bearings with z < 0).
CameraModel fisheyeCamera() {
  return CameraModel(752, 480, 250.0, 250.0, 375.5, 239.5, DistortionModel::kEquidistant,
                     {0.0034, 0.0007, -0.0020, 0.0002});
}

/// Camera looking along world +x from `position` (world z up): x_c = -y_w, y_c = -z_w.
SE3d lookingAlongX(const Eigen::Vector3d& position) {
  Eigen::Matrix3d R_w_c;
  R_w_c << 0, 0, 1, -1, 0, 0, 0, -1, 0;
  return SE3d(R_w_c, position);
}

Quad makeQuad(const Eigen::Vector3d& origin, const Eigen::Vector3d& edge_u,
              const Eigen::Vector3d& edge_v, int texture,
              const Eigen::Vector2d& offset_m = Eigen::Vector2d::Zero()) {
  Quad quad;
  quad.origin = origin;
  quad.edge_u = edge_u;
  quad.edge_v = edge_v;
  quad.texture = texture;
  quad.texture_offset_m = offset_m;
  return quad;
}

SceneObject staticObject(std::uint16_t instance_id, std::vector<Quad> quads) {
  SceneObject object;
  object.instance_id = instance_id;
  object.quads = std::move(quads);
  return object;
}

/// Four sides and a roof of a box standing on the object-frame origin (z up), length along x.
/// Sides run edge_v downwards so upright textures show upright.
std::vector<Quad> boxQuads(const Eigen::Vector3d& size, int texture, double texture_u_m) {
  const double l = size.x(), w = size.y(), h = size.z();
  const Eigen::Vector3d down(0, 0, -h);
  std::vector<Quad> quads;
  quads.push_back(makeQuad({-l / 2, -w / 2, h}, {l, 0, 0}, down, texture, {texture_u_m, 0}));
  quads.push_back(makeQuad({l / 2, -w / 2, h}, {0, w, 0}, down, texture, {texture_u_m + l, 0}));
  quads.push_back(makeQuad({l / 2, w / 2, h}, {-l, 0, 0}, down, texture, {texture_u_m + l + w, 0}));
  quads.push_back(
      makeQuad({-l / 2, w / 2, h}, {0, -w, 0}, down, texture, {texture_u_m + 2 * l + w, 0}));
  quads.push_back(makeQuad({-l / 2, -w / 2, h}, {l, 0, 0}, {0, w, 0}, texture, {texture_u_m, h}));
  return quads;
}

/// An agent driving or walking along the street (world x) at `speed` [m/s], facing its
/// direction of travel, present only between enter_ns and leave_ns.
SceneObject movingBox(std::uint16_t id, ObjectClass object_class, const Eigen::Vector3d& start,
                      double speed, const Eigen::Vector3d& size, int texture, TimeNs enter_ns,
                      TimeNs leave_ns) {
  SceneObject object;
  object.instance_id = id;
  object.object_class = object_class;
  object.quads = boxQuads(size, texture, 2.0 * id);
  object.T_w_o = [=](TimeNs t_ns) -> std::optional<SE3d> {
    if (t_ns < enter_ns || t_ns > leave_ns) return std::nullopt;
    const double yaw = speed >= 0.0 ? 0.0 : M_PI;
    return SE3d(Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix(),
                start + Eigen::Vector3d(speed * nsToSeconds(t_ns), 0, 0));
  };
  object.is_moving = [speed](TimeNs) { return speed != 0.0; };
  return object;
}

/// A street 80 m long (along x) and 16 m wide between two facades, with parked and moving cars,
/// pedestrians and clutter (poles, signs, bins): about 300 quads.
Scene makeStreetScene(int ground_texture, int facade_texture, int vehicle_texture,
                      int pedestrian_texture, int clutter_texture) {
  Scene scene;
  std::vector<Quad> world;
  for (int k = 0; k < 4; ++k) {  // ground in 20 m tiles sharing one texture
    world.push_back(
        makeQuad({-10.0 + 20 * k, 8, 0}, {20, 0, 0}, {0, -16, 0}, ground_texture, {20.0 * k, 0.0}));
  }
  for (int k = 0; k < 4; ++k) {  // facades, top row of the texture at the roof line
    world.push_back(makeQuad({-10.0 + 20 * k, 8, 15}, {20, 0, 0}, {0, 0, -15}, facade_texture,
                             {20.0 * k, 0.0}));
    world.push_back(makeQuad({-10.0 + 20 * k, -8, 15}, {20, 0, 0}, {0, 0, -15}, facade_texture,
                             {20.0 * k, 15.0}));
  }
  std::mt19937 rng(4);
  std::uniform_real_distribution<double> along(-5.0, 70.0), unit(0.0, 1.0);
  for (int k = 0; k < 40; ++k) {  // poles with signs, bins, bollards: 1 box = 5 quads
    const double x = along(rng), y = unit(rng) < 0.5 ? -7.2 : 7.2;
    const Eigen::Vector3d size =
        unit(rng) < 0.5 ? Eigen::Vector3d(0.12, 0.12, 3.0) : Eigen::Vector3d(0.6, 0.6, 1.0);
    for (Quad quad : boxQuads(size, clutter_texture, 3.0 * k)) {
      quad.origin += Eigen::Vector3d(x, y, 0);
      world.push_back(quad);
    }
    if (size.z() > 2.0) {
      world.push_back(
          makeQuad({x, y - 0.3, 3.0}, {0, 0.6, 0}, {0, 0, -0.6}, clutter_texture, {3.0 * k, 5.0}));
    }
  }
  scene.objects.push_back(staticObject(0, std::move(world)));
  std::uint16_t id = 1;
  for (int k = 0; k < 12; ++k, ++id) {  // cars: parked along the kerbs or driving
    const bool parked = k % 3 == 0;
    const double x = 4.0 + 6.0 * k;
    const double lane = parked ? (k % 2 ? 5.5 : -5.5) : (k % 2 ? 2.0 : -2.0);
    scene.objects.push_back(movingBox(id, ObjectClass::kVehicle, {x, lane, 0},
                                      parked ? 0.0 : (k % 2 ? -3.0 : 3.0), {4.5, 1.8, 1.5},
                                      vehicle_texture, 0, 1'000'000'000'000));
  }
  for (int k = 0; k < 8; ++k, ++id) {  // pedestrians on the pavements
    scene.objects.push_back(movingBox(id, ObjectClass::kPedestrian,
                                      {3.0 + 7.0 * k, k % 2 ? 6.5 : -6.5, 0}, k % 2 ? 1.2 : -1.2,
                                      {0.35, 0.5, 1.75}, pedestrian_texture, 0, 1'000'000'000'000));
  }
  return scene;
}

Scene makeTexturedStreet() {
  Scene scene;
  const auto add = [&](TextureStyle style, int width, int height, std::uint64_t seed) {
    ProceduralTextureOptions options;
    options.style = style;
    options.width = width;
    options.height = height;
    options.seed = seed;
    options.texel_m = 0.01;
    scene.textures.push_back(Texture::procedural(options));
    return static_cast<int>(scene.textures.size()) - 1;
  };
  const int ground = add(TextureStyle::kGround, 8000, 1600, 1);
  const int facade = add(TextureStyle::kFacade, 8000, 3000, 2);
  const int vehicle = add(TextureStyle::kVehicle, 2400, 300, 3);
  const int pedestrian = add(TextureStyle::kPedestrian, 800, 200, 4);
  const int clutter = add(TextureStyle::kIndoor, 1200, 600, 5);
  Scene street = makeStreetScene(ground, facade, vehicle, pedestrian, clutter);
  street.textures = std::move(scene.textures);
  return street;
}

/// Bilinear value of a CV_8UC1 or CV_32FC1 image at a sub-pixel position (centres at integers).
double bilinearAt(const cv::Mat& image, const Eigen::Vector2d& pixel) {
  const int c = static_cast<int>(std::floor(pixel.x()));
  const int r = static_cast<int>(std::floor(pixel.y()));
  const double fx = pixel.x() - c, fy = pixel.y() - r;
  const auto at = [&](int rr, int cc) {
    return image.depth() == CV_32F ? static_cast<double>(image.at<float>(rr, cc))
                                   : static_cast<double>(image.at<std::uint8_t>(rr, cc));
  };
  return (1 - fy) * ((1 - fx) * at(r, c) + fx * at(r, c + 1)) +
         fy * ((1 - fx) * at(r + 1, c) + fx * at(r + 1, c + 1));
}

bool identical(const cv::Mat& a, const cv::Mat& b) {
  if (a.size() != b.size() || a.type() != b.type()) return false;
  return std::memcmp(a.data, b.data, a.total() * a.elemSize()) == 0;
}

// ------------------------------------------------------------------------------------------------
// (a) Geometry

TEST(RendererTest, FrontoParallelQuadCoversExactlyThePixelCentresInsideItsProjection) {
  const CameraModel camera = pinholeCamera();
  const Renderer renderer(camera);
  Scene scene;
  scene.textures.push_back(Texture::uniform(200));
  const double z = 4.0, x0 = -1.23, x1 = 0.87, y0 = -0.61, y1 = 0.94;
  scene.objects.push_back(
      staticObject(7, {makeQuad({x0, y0, z}, {x1 - x0, 0, 0}, {0, y1 - y0, 0}, 0)}));
  RenderOptions options;
  options.background_gray = 10;
  const RenderResult result = renderer.render(scene, SE3d(), 0, options);

  const double u0 = camera.cx() + camera.fx() * x0 / z, u1 = camera.cx() + camera.fx() * x1 / z;
  const double v0 = camera.cy() + camera.fy() * y0 / z, v1 = camera.cy() + camera.fy() * y1 / z;
  for (const double bound : {u0, u1, v0, v1}) {  // no pixel centre sits on the outline
    ASSERT_GT(std::abs(bound - std::round(bound)), 1e-3);
  }
  int mismatches = 0, covered = 0;
  for (int r = 0; r < camera.height(); ++r) {
    for (int c = 0; c < camera.width(); ++c) {
      const bool inside = c >= u0 && c <= u1 && r >= v0 && r <= v1;
      covered += inside;
      const float depth = result.depth.at<float>(r, c);
      const bool ok = inside ? result.instance.at<std::uint16_t>(r, c) == 7 &&
                                   std::abs(depth - z) < 1e-5 &&
                                   result.image.at<std::uint8_t>(r, c) == 200
                             : result.instance.at<std::uint16_t>(r, c) == 0 && std::isinf(depth) &&
                                   result.image.at<std::uint8_t>(r, c) == 10;
      mismatches += !ok;
    }
  }
  EXPECT_EQ(mismatches, 0);
  EXPECT_EQ(covered, (static_cast<int>(std::floor(u1)) - static_cast<int>(std::ceil(u0)) + 1) *
                         (static_cast<int>(std::floor(v1)) - static_cast<int>(std::ceil(v0)) + 1));
}

TEST(RendererTest, DistortedCameraProjectionLandsWhereTheRenderedDepthMatches) {
  const CameraModel camera = eurocCamera();
  const Renderer renderer(camera);
  Scene scene;
  scene.textures.push_back(Texture::uniform(100));
  // A plane tilted by 22 degrees, 5 m ahead, large enough to fill the whole view.
  const SE3d T_c_q(expSO3(Eigen::Vector3d(0.2, -0.3, 0.1)), Eigen::Vector3d(0.3, -0.2, 5.0));
  const Eigen::Vector3d origin = T_c_q * Eigen::Vector3d(-30, -30, 0);
  const Eigen::Vector3d edge_u = T_c_q.rotation() * Eigen::Vector3d(60, 0, 0);
  const Eigen::Vector3d edge_v = T_c_q.rotation() * Eigen::Vector3d(0, 60, 0);
  scene.objects.push_back(staticObject(3, {makeQuad(origin, edge_u, edge_v, 0)}));
  const RenderResult result = renderer.render(scene, SE3d(), 0, {});
  ASSERT_EQ(cv::countNonZero(result.instance != 3), 0);

  std::mt19937 rng(2);
  std::uniform_real_distribution<double> edge(0.0, 1.0);
  int checked = 0, near_border = 0;
  double max_error = 0.0;
  while (checked < 2000) {
    const Eigen::Vector3d p_c = origin + edge(rng) * edge_u + edge(rng) * edge_v;
    const auto pixel = camera.project(p_c);
    if (!pixel || !camera.isInImage(*pixel, 1.0)) continue;
    const int c = static_cast<int>(std::lround(pixel->x())),
              r = static_cast<int>(std::lround(pixel->y()));
    ASSERT_EQ(result.instance.at<std::uint16_t>(r, c), 3);
    ++checked;
    near_border += (*pixel - Eigen::Vector2d(camera.cx(), camera.cy())).norm() > 350.0;
    // Depth varies across the pixel: allow the local gradient times the rounding offset (plus
    // 10% for the curvature of depth over a distorted image).
    const double du =
        0.5 * std::abs(result.depth.at<float>(r, c + 1) - result.depth.at<float>(r, c - 1));
    const double dv =
        0.5 * std::abs(result.depth.at<float>(r + 1, c) - result.depth.at<float>(r - 1, c));
    const double allowed =
        1.1 * (du * std::abs(pixel->x() - c) + dv * std::abs(pixel->y() - r)) + 1e-4;
    ASSERT_LE(std::abs(result.depth.at<float>(r, c) - p_c.z()), allowed) << pixel->transpose();
    // Interpolated between the four pixel centres around it, the depth is the point's z.
    const double error = std::abs(bilinearAt(result.depth, *pixel) - p_c.z());
    max_error = std::max(max_error, error);
    ASSERT_LT(error, 1e-4 * p_c.z()) << "pixel " << pixel->transpose();
  }
  EXPECT_GT(near_border, 100);  // strongly distorted corners were covered
  std::cout << "max |interpolated depth - z| at projected points: " << max_error << " m\n";
}

TEST(RendererTest, DistortedStraightEdgeFollowsTheProjectedCurve) {
  const CameraModel camera = eurocCamera();
  const Renderer renderer(camera);
  Scene scene;
  scene.textures.push_back(Texture::uniform(255));
  // Vertical edge x = -2.1 at z = 3: near the left border, where radtan bends it most.
  const double x_edge = -2.1, z = 3.0;
  scene.objects.push_back(staticObject(1, {makeQuad({x_edge, -5, z}, {10, 0, 0}, {0, 10, 0}, 0)}));
  const RenderResult result = renderer.render(scene, SE3d(), 0, {});
  double min_u = 1e9, max_u = -1e9, max_error = 0.0;
  for (int r = 0; r < camera.height(); ++r) {
    // Where the projected edge crosses this row: bisection on the edge's y.
    double lo = -5.0, hi = 5.0;
    for (int i = 0; i < 60; ++i) {
      const double mid = 0.5 * (lo + hi);
      (camera.project({x_edge, mid, z})->y() < r ? lo : hi) = mid;
    }
    const double u_edge = camera.project({x_edge, lo, z})->x();
    min_u = std::min(min_u, u_edge);
    max_u = std::max(max_u, u_edge);
    // First covered column of this row.
    int first = camera.width();
    for (int c = 0; c < camera.width(); ++c) {
      if (result.instance.at<std::uint16_t>(r, c) == 1) {
        first = c;
        break;
      }
    }
    ASSERT_EQ(first, static_cast<int>(std::ceil(u_edge))) << "row " << r << " edge at " << u_edge;
    max_error = std::max(max_error, std::abs(first - u_edge));
  }
  EXPECT_GT(max_u - min_u, 10.0);  // the straight edge is visibly curved
}

// ------------------------------------------------------------------------------------------------
// (b) Occlusion

TEST(RendererTest, NearQuadOccludesFarQuadWhateverTheOrder) {
  const CameraModel camera = pinholeCamera();
  const Renderer renderer(camera);
  for (const bool near_first : {true, false}) {
    Scene scene;
    scene.textures.push_back(Texture::uniform(50));
    scene.textures.push_back(Texture::uniform(150));
    const SceneObject near =
        staticObject(1, {makeQuad({-1.0, -0.5, 3.0}, {1.5, 0, 0}, {0, 1, 0}, 0)});
    const SceneObject far = staticObject(2, {makeQuad({-0.5, -1.5, 6.0}, {3, 0, 0}, {0, 3, 0}, 1)});
    scene.objects =
        near_first ? std::vector<SceneObject>{near, far} : std::vector<SceneObject>{far, near};
    const RenderResult result = renderer.render(scene, SE3d(), 0, {});
    int overlap = 0, far_only = 0;
    for (int r = 0; r < camera.height(); ++r) {
      for (int c = 0; c < camera.width(); ++c) {
        const Eigen::Vector3d ray = renderer.camera().unproject(Eigen::Vector2d(c, r)).value();
        const Eigen::Vector2d on_near = ray.head<2>() * (3.0 / ray.z());
        const Eigen::Vector2d on_far = ray.head<2>() * (6.0 / ray.z());
        const bool in_near =
            on_near.x() >= -1.0 && on_near.x() <= 0.5 && on_near.y() >= -0.5 && on_near.y() <= 0.5;
        const bool in_far =
            on_far.x() >= -0.5 && on_far.x() <= 2.5 && on_far.y() >= -1.5 && on_far.y() <= 1.5;
        const auto id = result.instance.at<std::uint16_t>(r, c);
        const float depth = result.depth.at<float>(r, c);
        if (in_near && in_far) {
          ++overlap;
          ASSERT_EQ(id, 1);
          ASSERT_NEAR(depth, 3.0, 1e-5);
          ASSERT_EQ(result.image.at<std::uint8_t>(r, c), 50);
        } else if (in_far) {
          ++far_only;
          ASSERT_EQ(id, 2);
          ASSERT_NEAR(depth, 6.0, 1e-5);
          ASSERT_EQ(result.image.at<std::uint8_t>(r, c), 150);
        }
      }
    }
    EXPECT_GT(overlap, 5000);
    EXPECT_GT(far_only, 5000);
  }
}

// ------------------------------------------------------------------------------------------------
// (c) Mask consistency

TEST(RendererTest, InstanceMaskIsExactlyWhereAgentsAreSeen) {
  // World black, agents white, black sky, no noise: the image says which object each pixel shows.
  Scene scene = makeStreetScene(0, 0, 1, 1, 0);
  scene.textures = {Texture::uniform(0), Texture::uniform(255)};
  scene.objects.push_back(movingBox(99, ObjectClass::kPedestrian, {9.0, 0.5, 0}, 0.0,
                                    {0.4, 0.5, 1.8}, 1, 10 * kNsPerSecond, 20 * kNsPerSecond));
  RenderOptions options;
  options.background_gray = 0;
  for (const CameraModel& camera : {pinholeCamera(), eurocCamera(), fisheyeCamera()}) {
    const Renderer renderer(camera);
    for (int frame = 0; frame < 6; ++frame) {
      const TimeNs t_ns = frame * 4 * kNsPerSecond;
      const SE3d T_w_c = lookingAlongX({-4.0 + 2.0 * frame, 0.3 * frame - 1.0, 1.5});
      const RenderResult result = renderer.render(scene, T_w_c, t_ns, options);
      const cv::Mat bright = result.image > 127, agent = result.instance != 0;
      EXPECT_EQ(cv::countNonZero(bright != agent), 0) << "frame " << frame;
      EXPECT_GT(cv::countNonZero(agent), 1000) << "frame " << frame;  // agents are in view
      // The pedestrian with id 99 is in the world only from 10 s to 20 s.
      const bool present = t_ns >= 10 * kNsPerSecond && t_ns <= 20 * kNsPerSecond;
      if (!present) {
        EXPECT_EQ(cv::countNonZero(result.instance == 99), 0) << "frame " << frame;
      }
      cv::Mat hit_depth;
      cv::compare(result.depth, std::numeric_limits<float>::max(), hit_depth, cv::CMP_LE);
      EXPECT_EQ(cv::countNonZero(agent & ~hit_depth), 0);
    }
  }
}

// ------------------------------------------------------------------------------------------------
// (d) Photometric consistency

TEST(RendererTest, StereoCamerasSeeTheSameBrightnessAtTheSamePoint) {
  const CameraModel camera = eurocCamera();
  const Renderer renderer(camera);
  Scene scene;
  ProceduralTextureOptions texture_options;
  texture_options.style = TextureStyle::kFacade;
  texture_options.width = 1200;
  texture_options.height = 900;
  texture_options.texel_m = 0.005;
  scene.textures.push_back(Texture::procedural(texture_options));
  // A wall 6 x 4.5 m, 4 to 6 m away and slanted by 25 degrees.
  const Eigen::Matrix3d R = Eigen::AngleAxisd(0.44, Eigen::Vector3d::UnitY()).toRotationMatrix();
  const Eigen::Vector3d origin(-3.0, -2.2, 5.0), edge_u = R * Eigen::Vector3d(6, 0, 0),
                                                 edge_v = R * Eigen::Vector3d(0, 4.5, 0);
  scene.objects.push_back(staticObject(
      0, {makeQuad(origin - 0.5 * edge_u + Eigen::Vector3d(3, 0, 0), edge_u, edge_v, 0)}));
  const Quad& wall = scene.objects[0].quads[0];
  const SE3d T_w_left;
  const SE3d T_w_right(Eigen::Matrix3d::Identity(), Eigen::Vector3d(0.11, 0, 0));
  const RenderResult left = renderer.render(scene, T_w_left, 0, {});
  const RenderResult right = renderer.render(scene, T_w_right, 0, {});

  std::mt19937 rng(5);
  std::uniform_real_distribution<double> edge(0.05, 0.95);
  std::vector<double> left_values, right_values;
  while (left_values.size() < 3000) {
    const Eigen::Vector3d p_w = wall.origin + edge(rng) * wall.edge_u + edge(rng) * wall.edge_v;
    const auto in_left = camera.project(T_w_left.inverse() * p_w);
    const auto in_right = camera.project(T_w_right.inverse() * p_w);
    if (!in_left || !in_right || !camera.isInImage(*in_left, 2) ||
        !camera.isInImage(*in_right, 2)) {
      continue;
    }
    left_values.push_back(bilinearAt(left.image, *in_left));
    right_values.push_back(bilinearAt(right.image, *in_right));
  }
  double same_point = 0.0, unrelated = 0.0;
  const std::size_t n = left_values.size();
  for (std::size_t i = 0; i < n; ++i) {
    same_point += std::abs(left_values[i] - right_values[i]);
    unrelated += std::abs(left_values[i] - right_values[(i + 7) % n]);
  }
  same_point /= static_cast<double>(n);
  unrelated /= static_cast<double>(n);
  std::cout << "mean |left - right| at the same 3D point: " << same_point
            << " gray levels; at unrelated points: " << unrelated << "\n";
  EXPECT_LT(same_point, 6.0);
  EXPECT_LT(same_point, 0.15 * unrelated);
}

// ------------------------------------------------------------------------------------------------
// (e) Determinism, threads, noise and motion blur

class RendererStreetTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() { street_ = new Scene(makeTexturedStreet()); }
  static void TearDownTestSuite() {
    delete street_;
    street_ = nullptr;
  }
  static std::function<SE3d(TimeNs)> drivingCamera() {
    return [](TimeNs t_ns) {
      const double t = nsToSeconds(t_ns);
      const SE3d T_w_c = lookingAlongX({-3.0 + 8.0 * t, 0.5 * std::sin(t), 1.6});
      const Eigen::Matrix3d yaw =
          Eigen::AngleAxisd(0.2 * std::sin(2 * t), Eigen::Vector3d::UnitZ()).toRotationMatrix();
      return SE3d(yaw * T_w_c.rotation(), T_w_c.t);
    };
  }
  static Scene* street_;
};
Scene* RendererStreetTest::street_ = nullptr;

TEST_F(RendererStreetTest, SameInputsGiveIdenticalOutputsWhateverTheThreads) {
  const Renderer renderer(eurocCamera());
  RenderOptions options;
  options.noise_sigma = 2.0;
  options.blur_samples = 3;
  options.exposure_s = 0.01;
  options.seed = 42;
  const TimeNs t_ns = 1'500'000'000;
  options.threads = 2;
  const RenderResult a = renderer.render(*street_, drivingCamera(), t_ns, options);
  const RenderResult b = renderer.render(*street_, drivingCamera(), t_ns, options);
  EXPECT_TRUE(identical(a.image, b.image));
  for (const int threads : {1, 3, 5}) {
    options.threads = threads;
    const RenderResult c = renderer.render(*street_, drivingCamera(), t_ns, options);
    EXPECT_TRUE(identical(a.image, c.image)) << threads << " threads";
    EXPECT_TRUE(identical(a.instance, c.instance)) << threads << " threads";
    EXPECT_TRUE(identical(a.depth, c.depth)) << threads << " threads";
  }
  // The noise is a function of seed and time: another frame or seed gets other noise.
  options.seed = 43;
  const RenderResult other_seed = renderer.render(*street_, drivingCamera(), t_ns, options);
  EXPECT_FALSE(identical(a.image, other_seed.image));
  EXPECT_TRUE(identical(a.instance, other_seed.instance));
}

TEST_F(RendererStreetTest, NoiseHasTheRequestedStrength) {
  const Renderer renderer(eurocCamera());
  RenderOptions options;
  const RenderResult clean = renderer.render(*street_, drivingCamera(), 0, options);
  options.noise_sigma = 3.0;
  const RenderResult noisy = renderer.render(*street_, drivingCamera(), 0, options);
  cv::Mat difference;
  cv::subtract(noisy.image, clean.image, difference, cv::noArray(), CV_32F);
  cv::Scalar mean, stddev;
  // Pixels away from 0 and 255, where the noise is not clipped.
  cv::meanStdDev(difference, mean, stddev, (clean.image > 20) & (clean.image < 235));
  EXPECT_NEAR(mean[0], 0.0, 0.05);
  EXPECT_NEAR(stddev[0], std::sqrt(9.0 + 1.0 / 12.0), 0.1);  // noise plus rounding
}

TEST_F(RendererStreetTest, MotionBlurSmearsTheImageButNotTheMask) {
  const Renderer renderer(eurocCamera());
  const TimeNs t_ns = 2'000'000'000;
  RenderOptions options;
  const RenderResult sharp = renderer.render(*street_, drivingCamera(), t_ns, options);
  options.blur_samples = 4;
  options.exposure_s = 0.0;  // sub-frames all at t_ns: same image
  const RenderResult zero_exposure = renderer.render(*street_, drivingCamera(), t_ns, options);
  EXPECT_LE(cv::norm(sharp.image, zero_exposure.image, cv::NORM_INF), 1.0);
  options.exposure_s = 0.02;  // 16 cm of travel at 8 m/s
  const RenderResult blurred = renderer.render(*street_, drivingCamera(), t_ns, options);
  EXPECT_TRUE(identical(sharp.instance, blurred.instance));
  EXPECT_TRUE(identical(sharp.depth, blurred.depth));
  cv::Mat sharp_edges, blurred_edges;
  cv::Laplacian(sharp.image, sharp_edges, CV_32F);
  cv::Laplacian(blurred.image, blurred_edges, CV_32F);
  const double sharpness = cv::norm(sharp_edges, cv::NORM_L1);
  const double blurredness = cv::norm(blurred_edges, cv::NORM_L1);
  std::cout << "Laplacian energy sharp " << sharpness << ", blurred " << blurredness << "\n";
  EXPECT_LT(blurredness, 0.8 * sharpness);
}

TEST_F(RendererStreetTest, StreetFrameHasManyTrackableCornersAndTimingIsReported) {
  const Renderer renderer(eurocCamera());
  std::size_t quad_count = 0;
  for (const SceneObject& object : street_->objects)
    quad_count += object.quads.size();
  RenderOptions options;
  options.noise_sigma = 1.0;
  RenderResult result;
  for (const int threads : {1, 2}) {
    options.threads = threads;
    constexpr int kFrames = 20;
    const auto start = std::chrono::steady_clock::now();
    for (int frame = 0; frame < kFrames; ++frame) {
      result = renderer.render(*street_, drivingCamera(), frame * 50'000'000, options);
    }
    const double ms =
        std::chrono::duration<double, std::milli>(std::chrono::steady_clock::now() - start)
            .count() /
        kFrames;
    std::cout << "street scene, " << quad_count << " quads, 752x480, " << threads
              << " thread(s): " << ms << " ms per frame\n";
  }
  std::vector<cv::KeyPoint> corners;
  cv::FAST(result.image, corners, 20, true);
  std::cout << "FAST corners in the last frame: " << corners.size() << "\n";
  EXPECT_GT(quad_count, 250u);
  EXPECT_GT(corners.size(), 500u);
  EXPECT_GT(cv::countNonZero(result.instance != 0), 1000);
  // Set SUPERDYNA_RENDER_DEBUG_DIR to look at the frame, its mask and its depth.
  if (const char* dir = std::getenv("SUPERDYNA_RENDER_DEBUG_DIR"); dir != nullptr && *dir) {
    const std::filesystem::path out(dir);
    std::filesystem::create_directories(out);
    cv::imwrite((out / "street_image.png").string(), result.image);
    cv::Mat mask_vis, depth_vis;
    result.instance.convertTo(mask_vis, CV_8U, 12.0);
    cv::applyColorMap(mask_vis, mask_vis, cv::COLORMAP_JET);
    mask_vis.setTo(cv::Scalar::all(0), result.instance == 0);
    cv::imwrite((out / "street_instance.png").string(), mask_vis);
    cv::Mat finite_depth = cv::min(result.depth, 60.0f);
    finite_depth.convertTo(depth_vis, CV_8U, 255.0 / 60.0);
    cv::imwrite((out / "street_depth.png").string(), depth_vis);
    cv::Mat blend;
    cv::cvtColor(result.image, blend, cv::COLOR_GRAY2BGR);
    cv::addWeighted(blend, 0.6, mask_vis, 0.4, 0.0, blend);
    cv::imwrite((out / "street_overlay.png").string(), blend);
  }
}

TEST(RendererTest, RejectsInvalidOptionsAndScenes) {
  const Renderer renderer(pinholeCamera());
  Scene scene;
  scene.textures.push_back(Texture());
  scene.objects.push_back(staticObject(0, {makeQuad({-1, -1, 3}, {2, 0, 0}, {0, 2, 0}, 0)}));
  RenderOptions options;
  options.blur_samples = -1;
  EXPECT_THROW(renderer.render(scene, SE3d(), 0, options), OptionError);
  options = {};
  options.near_m = 0.0;
  EXPECT_THROW(renderer.render(scene, SE3d(), 0, options), OptionError);
  options = {};
  options.noise_sigma = -1.0;
  EXPECT_THROW(renderer.render(scene, SE3d(), 0, options), OptionError);
  options = {};
  options.threads = 0;
  EXPECT_THROW(renderer.render(scene, SE3d(), 0, options), OptionError);
  EXPECT_THROW(renderer.render(scene, std::function<SE3d(TimeNs)>(), 0, RenderOptions{}),
               OptionError);
  scene.objects[0].quads[0].texture = 1;
  EXPECT_THROW(renderer.render(scene, SE3d(), 0, RenderOptions{}), OptionError);
  EXPECT_THROW(Renderer{CameraModel{}}, OptionError);
}

TEST(RendererTest, SinglePixelCameraWorks) {
  const Renderer renderer(CameraModel(1, 1, 100.0, 100.0, 0.0, 0.0));
  Scene scene;
  scene.textures.push_back(Texture::uniform(77));
  scene.objects.push_back(staticObject(5, {makeQuad({-1, -1, 2}, {2, 0, 0}, {0, 2, 0}, 0)}));
  const RenderResult result = renderer.render(scene, SE3d(), 0, {});
  EXPECT_EQ(result.image.at<std::uint8_t>(0, 0), 77);
  EXPECT_EQ(result.instance.at<std::uint16_t>(0, 0), 5);
  EXPECT_FLOAT_EQ(result.depth.at<float>(0, 0), 2.0f);
}

TEST(RendererTest, QuadsBehindOrCrossingTheCameraAreHandled) {
  const CameraModel camera = pinholeCamera();
  const Renderer renderer(camera);
  Scene scene;
  scene.textures.push_back(Texture::uniform(255));
  // Entirely behind: invisible. A floor running from behind the camera to far ahead: visible
  // below the horizon only, and its depth grows towards the horizon.
  scene.objects.push_back(staticObject(1, {makeQuad({-5, -1, -3}, {10, 0, 0}, {0, 2, 0}, 0)}));
  scene.objects.push_back(
      staticObject(2, {makeQuad({-500, 1.5, -20}, {1000, 0, 0}, {0, 0, 200}, 0)}));
  RenderOptions options;
  options.background_gray = 0;
  const RenderResult result = renderer.render(scene, SE3d(), 0, options);
  EXPECT_EQ(cv::countNonZero(result.instance == 1), 0);
  const int horizon = static_cast<int>(std::ceil(camera.cy()));
  EXPECT_EQ(cv::countNonZero(result.instance(cv::Rect(0, 0, 752, horizon)) != 0), 0);
  // Rows from 250 down see the floor closer than its far end (z = 180 m at row 247.5).
  EXPECT_EQ(cv::countNonZero(result.instance(cv::Rect(0, 250, 752, 230)) != 2), 0);
  // Floor 1.5 m below the camera: z = 1.5 * fy / (v - cy).
  for (const int r : {300, 400, 479}) {
    EXPECT_NEAR(result.depth.at<float>(r, 100), 1.5 * camera.fy() / (r - camera.cy()), 1e-4);
  }
}

}  // namespace
}  // namespace superdyna::sim
