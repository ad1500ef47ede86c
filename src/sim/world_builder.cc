#include "superdyna/sim/world_builder.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <random>
#include <set>
#include <stdexcept>
#include <utility>

#include "superdyna/core/error.h"
#include "superdyna/sim/agents.h"
#include "superdyna/sim/hash.h"

namespace superdyna::sim {

namespace {

constexpr TimeNs kPathSamplePeriodNs = 100 * kNsPerMillisecond;

/// The camera path sampled on the ground plane: positions and horizontal viewing directions.
struct PathSamples {
  std::vector<TimeNs> t_ns;
  std::vector<Eigen::Vector3d> position;
  std::vector<Eigen::Vector2d> forward_xy;  ///< Unit horizontal viewing direction.
  Eigen::Vector2d min_xy, max_xy;
  double min_z = 0.0, max_z = 0.0;

  /// Smallest horizontal distance from `xy` to the path [m].
  double distanceTo(const Eigen::Vector2d& xy) const {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& p : position)
      best = std::min(best, (p.head<2>() - xy).norm());
    return best;
  }
  std::size_t indexAt(TimeNs t) const {
    const auto it = std::lower_bound(t_ns.begin(), t_ns.end(), t);
    return std::min<std::size_t>(static_cast<std::size_t>(it - t_ns.begin()), t_ns.size() - 1);
  }
};

PathSamples samplePath(const CameraPath& path) {
  PathSamples s;
  Eigen::Vector2d last_forward = Eigen::Vector2d::UnitX();
  for (TimeNs t = path.range.begin; t <= path.range.end; t += kPathSamplePeriodNs) {
    const SE3d T_w_c = path.T_w_c(t);
    const Eigen::Vector3d optical_axis = T_w_c.rotation().col(2);
    Eigen::Vector2d forward = optical_axis.head<2>();
    // Looking nearly straight up or down: keep the last horizontal direction.
    if (forward.norm() > 0.2) last_forward = forward.normalized();
    s.t_ns.push_back(t);
    s.position.push_back(T_w_c.t);
    s.forward_xy.push_back(last_forward);
  }
  if (s.position.empty()) throw OptionError("camera_path", "empty time range");
  s.min_xy = s.max_xy = s.position.front().head<2>();
  s.min_z = s.max_z = s.position.front().z();
  for (const auto& p : s.position) {
    s.min_xy = s.min_xy.cwiseMin(p.head<2>());
    s.max_xy = s.max_xy.cwiseMax(p.head<2>());
    s.min_z = std::min(s.min_z, p.z());
    s.max_z = std::max(s.max_z, p.z());
  }
  return s;
}

/// Random numbers of one build, seeded once. No two draws are unsequenced, as two arguments or
/// operands of one expression are (their order would be the compiler's: gcc and clang differ;
/// braced lists are evaluated in order), as in texture.cc.
class Random {
 public:
  explicit Random(std::uint64_t seed) : rng_(seed) {}
  double uniform(double lo, double hi) {
    return std::uniform_real_distribution<double>(lo, hi)(rng_);
  }
  bool chance(double p) { return uniform(0.0, 1.0) < p; }
  int integer(int lo, int hi) { return std::uniform_int_distribution<int>(lo, hi)(rng_); }
  std::uint64_t seed() { return rng_(); }

 private:
  std::mt19937_64 rng_;
};

/// Layout constants of each scene type.
struct SceneLayout {
  double margin_m;       ///< Free space around the path's bounding box.
  double ground_tile_m;  ///< Ground split into tiles of at most this size.
  double texel_m;        ///< Ground / wall texel size.
  TextureStyle ground_style;
  double vehicle_share;  ///< Share of vehicles among agents (rest: pedestrians).
  double vehicle_speed_min, vehicle_speed_max;          ///< [m/s]
  double crossing_distance_min, crossing_distance_max;  ///< Ahead of the camera [m].
  double static_spacing_m;
  double min_extent_m;  ///< Smallest side of the world [m].
  /// Moving-agent slots per agent the level wants in view (measured: an agent is in view for
  /// roughly half of its life, slow parking traffic less).
  double slots_per_agent_in_view;  ///< Path
                                   ///< length between static agents.
};

SceneLayout layoutOf(SceneType scene) {
  switch (scene) {
    case SceneType::kStreet:
      return {30.0, 24.0, 0.02, TextureStyle::kGround, 0.6, 4.0, 12.0, 6.0, 18.0, 7.0, 80.0, 2.2};
    case SceneType::kParking:
      return {24.0, 24.0, 0.02, TextureStyle::kGround, 0.5, 2.0, 6.0, 5.0, 15.0, 5.0, 60.0, 3.0};
    case SceneType::kIndoor:
      return {4.0, 12.0, 0.008, TextureStyle::kIndoor, 0.0, 0.0, 0.0, 2.5, 7.0, 3.0, 16.0, 2.5};
  }
  return layoutOf(SceneType::kStreet);
}

/// Seeds of the mover patterns' and the unlabelled relabelling's random streams (mixed with the
/// seed): independent of the level's stream, which they must not disturb.
constexpr std::uint64_t kPatternStream = 0x7061747465726eULL;
constexpr std::uint64_t kUnlabelledStream = 0x756e6c6162656cULL;

/// What a mover pattern's groups are made of and how they move.
struct PatternSpec {
  ObjectClass object_class = ObjectClass::kVehicle;
  AgentSize size;
  int group_size = 1;
  double speed_min = 0.0, speed_max = 0.0;        ///< [m/s]
  double distance_min = 0.0, distance_max = 0.0;  ///< From the camera [m].
  double crossing_share = 0.5;      ///< Share of groups crossing the view (the rest move along it).
  double camera_clearance_m = 1.0;  ///< Between a member's footprint and the camera.
  double texture_width_m = 0.0, texture_height_m = 0.0, texel_m = 0.01;
  TextureStyle texture_style = TextureStyle::kVehicle;
};

PatternSpec patternSpec(const MoverPatternOptions& options) {
  PatternSpec spec;
  const bool people = options.pattern == MoverPattern::kCrowd;
  if (people) {
    spec = {ObjectClass::kPedestrian,
            pedestrianSize(),
            10,
            1.0,
            1.6,
            2.5,
            6.0,
            0.6,
            0.8,
            2.0,
            2.5,
            0.005,
            TextureStyle::kPedestrian};
  } else if (options.pattern == MoverPattern::kBus) {
    spec = {ObjectClass::kVehicle, busSize(), 1, 2.0, 5.0, 3.0, 6.0, 0.6, 1.5, 30.0, 4.0, 0.01,
            TextureStyle::kVehicle};
  } else {
    spec = {ObjectClass::kVehicle, vehicleSize(), 4, 2.0, 5.0, 4.0, 7.0, 0.5, 1.5, 13.0, 4.0, 0.01,
            TextureStyle::kVehicle};
  }
  if (options.slow) {
    spec.speed_min = people ? 0.3 : 0.5;
    spec.speed_max = people ? 0.6 : 1.5;
  }
  if (options.group_size > 0) spec.group_size = options.group_size;
  if (options.max_distance_m > 0.0) {
    spec.distance_min = options.min_distance_m;
    spec.distance_max = options.max_distance_m;
  }
  return spec;
}

/// Agents' textures (cars, people); the others are the static world's.
bool isAgentStyle(TextureStyle style) {
  return style == TextureStyle::kVehicle || style == TextureStyle::kPedestrian;
}

class WorldBuilder {
 public:
  WorldBuilder(const WorldOptions& options, const CameraPath& path)
      : options_(options),
        path_(path),
        samples_(samplePath(path)),
        layout_(layoutOf(options.scene)),
        random_(options.seed),
        pattern_random_(mix64(options.seed ^ kPatternStream)),
        unlabelled_random_(mix64(options.seed ^ kUnlabelledStream)) {
    world_.ground_z = samples_.min_z - options.ground_clearance_m;
    // The world surrounds the path with a margin, and is never smaller than the scene's minimum
    // size (a short or hovering path still gets a whole room or street block).
    const Eigen::Vector2d centre = 0.5 * (samples_.min_xy + samples_.max_xy);
    const Eigen::Vector2d half =
        (0.5 * (samples_.max_xy - samples_.min_xy).array() + layout_.margin_m)
            .max(0.5 * layout_.min_extent_m);
    region_min_ = centre - half;
    region_max_ = centre + half;
    world_.scene.objects.push_back(SceneObject{});  // the static world, instance 0
  }

  World build() {
    buildStatic();
    return buildAgents();
  }

  /// The static world: ground, room or buildings, clutter.
  void buildStatic() {
    addGround();
    if (options_.scene == SceneType::kIndoor) {
      addRoom();
    } else {
      addBuildings();
    }
    addClutter();
    finishSharedTextures();
  }

  /// The agents around this builder's path, drawn from its seed.
  World buildAgents() {
    addStaticAgents();
    addMovingAgents();
    addPatternGroups();
    relabelUnlabelledMovers();
    return std::move(world_);
  }

  /// Continues on the static world `other` built (its scene, ground, region and footprints); the
  /// agents then follow this builder's path and seed. Throws OptionError when this path leaves
  /// that world or passes within 0.5 m of one of its blocks.
  void adoptStaticWorld(WorldBuilder&& other, const ReusedWorldHint& hint) {
    world_ = std::move(other.world_);
    region_min_ = other.region_min_;
    region_max_ = other.region_max_;
    footprints_ = std::move(other.footprints_);
    for (std::size_t i = 0; i < samples_.position.size(); ++i) {
      const Eigen::Vector2d xy = samples_.position[i].head<2>();
      const bool blocked = overlapsFootprints(xy, Eigen::Vector2d::Constant(0.5), 0.0);
      if (insideRegion(xy, 0.5) && !blocked) continue;
      throw OptionError(
          "world-of",
          fmt::format("the camera path {} the reused world {:.2f} s into the trajectory (x {:.1f} "
                      "m, y {:.1f} m): choose a part of the trajectory within it{}",
                      blocked ? "runs into a block of" : "leaves",
                      nsToSeconds(samples_.t_ns[i] - hint.origin_ns), xy.x(), xy.y(),
                      hint.fits.empty() ? "" : "; " + hint.fits));
    }
  }

 private:
  std::vector<Quad>& staticQuads() { return world_.scene.objects.front().quads; }

  int addTexture(double width_m, double height_m, double texel_m, TextureStyle style) {
    return addTexture(width_m, height_m, texel_m, style, random_);
  }

  int addTexture(double width_m, double height_m, double texel_m, TextureStyle style,
                 Random& random) {
    const std::uint64_t seed = random.seed();
    if (!isAgentStyle(style) && options_.texture_variety > 0) {
      return sharedTexture(width_m, height_m, texel_m, style, seed);
    }
    world_.scene.textures.push_back(makeTexture(width_m, height_m, texel_m, style, seed));
    return static_cast<int>(world_.scene.textures.size()) - 1;
  }

  Texture makeTexture(double width_m, double height_m, double texel_m, TextureStyle style,
                      std::uint64_t seed) const {
    const double texel = texel_m * options_.texel_scale;
    const int width = std::clamp(static_cast<int>(std::ceil(width_m / texel)), 16, 8192);
    const int height = std::clamp(static_cast<int>(std::ceil(height_m / texel)), 16, 8192);
    const double effective_texel = std::max(width_m / width, height_m / height);
    const Texture texture =
        options_.photos.empty()
            ? Texture::procedural({.width = width,
                                   .height = height,
                                   .texel_m = effective_texel,
                                   .seed = seed,
                                   .style = style})
            : Texture::fromPhotos(options_.photos, width, height, effective_texel, seed);
    return isAgentStyle(style) ? texture : texture.withContrast(options_.background_contrast);
  }

  /// One of the `texture_variety` textures that the static surfaces of this style and texel size
  /// share: the first ones asked for make them (generated by finishSharedTextures() once their
  /// largest surface is known), later ones take the one their seed picks.
  int sharedTexture(double width_m, double height_m, double texel_m, TextureStyle style,
                    std::uint64_t seed) {
    std::vector<std::size_t>& kind = shared_kinds_[{static_cast<int>(style), texel_m}];
    const auto variety = static_cast<std::size_t>(options_.texture_variety);
    if (kind.size() < variety) {
      world_.scene.textures.emplace_back();  // generated by finishSharedTextures()
      kind.push_back(shared_textures_.size());
      shared_textures_.push_back({static_cast<int>(world_.scene.textures.size()) - 1, width_m,
                                  height_m, texel_m, style, seed});
      return shared_textures_.back().texture;
    }
    SharedTexture& shared = shared_textures_[kind[seed % variety]];
    shared.width_m = std::max(shared.width_m, width_m);
    shared.height_m = std::max(shared.height_m, height_m);
    return shared.texture;
  }

  void finishSharedTextures() {
    for (const SharedTexture& shared : shared_textures_) {
      world_.scene.textures[static_cast<std::size_t>(shared.texture)] =
          makeTexture(shared.width_m, shared.height_m, shared.texel_m, shared.style, shared.seed);
    }
  }

  void addGround() {
    const Eigen::Vector2d size = region_max_ - region_min_;
    const int nx = std::max(1, static_cast<int>(std::ceil(size.x() / layout_.ground_tile_m)));
    const int ny = std::max(1, static_cast<int>(std::ceil(size.y() / layout_.ground_tile_m)));
    const double tx = size.x() / nx, ty = size.y() / ny;
    for (int i = 0; i < nx; ++i) {
      for (int j = 0; j < ny; ++j) {
        const int texture = addTexture(tx, ty, layout_.texel_m, layout_.ground_style);
        staticQuads().push_back(
            {Eigen::Vector3d(region_min_.x() + i * tx, region_min_.y() + j * ty, world_.ground_z),
             Eigen::Vector3d(tx, 0, 0), Eigen::Vector3d(0, ty, 0), texture,
             Eigen::Vector2d::Zero()});
      }
    }
  }

  /// A vertical wall from a to b (on the ground), split into panels of at most `panel_m`.
  void addWall(const Eigen::Vector2d& a, const Eigen::Vector2d& b, double height, double texel_m,
               TextureStyle style, double panel_m) {
    const double length = (b - a).norm();
    const int panels = std::max(1, static_cast<int>(std::ceil(length / panel_m)));
    const Eigen::Vector2d step = (b - a) / panels;
    for (int k = 0; k < panels; ++k) {
      const int texture = addTexture(step.norm(), height, texel_m, style);
      const Eigen::Vector2d start = a + k * step;
      // From the top edge down: textures have the top of the wall at row 0.
      staticQuads().push_back({Eigen::Vector3d(start.x(), start.y(), world_.ground_z + height),
                               Eigen::Vector3d(step.x(), step.y(), 0.0),
                               Eigen::Vector3d(0.0, 0.0, -height), texture,
                               Eigen::Vector2d::Zero()});
    }
  }

  void addRoom() {
    const double height = std::max(3.5, samples_.max_z - world_.ground_z + 1.5);
    const Eigen::Vector2d c00 = region_min_, c11 = region_max_;
    const Eigen::Vector2d c10(c11.x(), c00.y()), c01(c00.x(), c11.y());
    addWall(c00, c10, height, layout_.texel_m, TextureStyle::kIndoor, 12.0);
    addWall(c10, c11, height, layout_.texel_m, TextureStyle::kIndoor, 12.0);
    addWall(c11, c01, height, layout_.texel_m, TextureStyle::kIndoor, 12.0);
    addWall(c01, c00, height, layout_.texel_m, TextureStyle::kIndoor, 12.0);
    const Eigen::Vector2d size = c11 - c00;
    const int texture =
        addTexture(size.x(), size.y(), 2.0 * layout_.texel_m, TextureStyle::kIndoor);
    staticQuads().push_back({Eigen::Vector3d(c00.x(), c00.y(), world_.ground_z + height),
                             Eigen::Vector3d(size.x(), 0, 0), Eigen::Vector3d(0, size.y(), 0),
                             texture, Eigen::Vector2d::Zero()});
  }

  /// A closed box of walls (no roof needed when taller than the camera can see over).
  void addBlock(const Eigen::Vector2d& centre, const Eigen::Vector2d& half, double height,
                double texel_m, TextureStyle style, bool with_top) {
    const Eigen::Vector2d c00 = centre - half, c11 = centre + half;
    const Eigen::Vector2d c10(c11.x(), c00.y()), c01(c00.x(), c11.y());
    addWall(c00, c10, height, texel_m, style, 24.0);
    addWall(c10, c11, height, texel_m, style, 24.0);
    addWall(c11, c01, height, texel_m, style, 24.0);
    addWall(c01, c00, height, texel_m, style, 24.0);
    if (!with_top) return;
    const int texture = addTexture(2 * half.x(), 2 * half.y(), texel_m, style);
    staticQuads().push_back({Eigen::Vector3d(c00.x(), c00.y(), world_.ground_z + height),
                             Eigen::Vector3d(2 * half.x(), 0, 0),
                             Eigen::Vector3d(0, 2 * half.y(), 0), texture,
                             Eigen::Vector2d::Zero()});
  }

  /// Distance from the path to a rectangle's border (0 when the path enters it).
  double pathClearance(const Eigen::Vector2d& centre, const Eigen::Vector2d& half) const {
    double best = std::numeric_limits<double>::infinity();
    for (const auto& p : samples_.position) {
      const Eigen::Vector2d d = ((p.head<2>() - centre).cwiseAbs() - half).cwiseMax(0.0);
      best = std::min(best, d.norm());
    }
    return best;
  }

  bool overlapsFootprints(const Eigen::Vector2d& centre, const Eigen::Vector2d& half,
                          double gap) const {
    for (const auto& [c, h] : footprints_) {
      if (std::abs(c.x() - centre.x()) < h.x() + half.x() + gap &&
          std::abs(c.y() - centre.y()) < h.y() + half.y() + gap) {
        return true;
      }
    }
    return false;
  }

  void addBuildings() {
    const bool parking = options_.scene == SceneType::kParking;
    const double cell = parking ? 20.0 : 14.0;
    const double min_clearance = parking ? 14.0 : 7.0;
    for (double x = region_min_.x() + cell / 2; x < region_max_.x(); x += cell) {
      for (double y = region_min_.y() + cell / 2; y < region_max_.y(); y += cell) {
        const double half_y = random_.uniform(3.5, 0.45 * cell);
        const Eigen::Vector2d half(random_.uniform(3.5, 0.45 * cell), half_y);
        const double centre_y = y + random_.uniform(-1.0, 1.0);
        const Eigen::Vector2d centre(x + random_.uniform(-1.0, 1.0), centre_y);
        if (pathClearance(centre, half) < min_clearance) continue;
        const double height = parking ? random_.uniform(4.0, 9.0) : random_.uniform(6.0, 22.0);
        addBlock(centre, half, height, 0.02, TextureStyle::kFacade, false);
        footprints_.push_back({centre, half});
      }
    }
  }

  void addClutter() {
    const bool indoor = options_.scene == SceneType::kIndoor;
    const int count = indoor ? 18 : 30;
    const double min_clearance = indoor ? 1.0 : 2.5;
    for (int attempt = 0, placed = 0; placed < count && attempt < 40 * count; ++attempt) {
      const double half_y = random_.uniform(0.2, indoor ? 0.8 : 1.2);
      const Eigen::Vector2d half(random_.uniform(0.2, indoor ? 0.8 : 1.2), half_y);
      const double centre_y =
          random_.uniform(region_min_.y() + half.y(), region_max_.y() - half.y());
      const Eigen::Vector2d centre(
          random_.uniform(region_min_.x() + half.x(), region_max_.x() - half.x()), centre_y);
      if (pathClearance(centre, half) < min_clearance || overlapsFootprints(centre, half, 0.3)) {
        continue;
      }
      const double height = random_.uniform(0.4, indoor ? 2.2 : 3.0);
      addBlock(centre, half, height, indoor ? 0.006 : 0.01,
               indoor ? TextureStyle::kIndoor : TextureStyle::kFacade, true);
      footprints_.push_back({centre, half});
      ++placed;
    }
  }

  ObjectClass randomAgentClass() {
    return random_.chance(layout_.vehicle_share) ? ObjectClass::kVehicle : ObjectClass::kPedestrian;
  }

  int agentTexture(ObjectClass object_class) {
    // A pool of textures per class: agents look different without one texture each.
    constexpr std::size_t kPoolSize = 12;
    auto& pool = object_class == ObjectClass::kVehicle ? vehicle_textures_ : pedestrian_textures_;
    if (pool.size() < kPoolSize) {
      const bool vehicle = object_class == ObjectClass::kVehicle;
      pool.push_back(addTexture(vehicle ? 13.0 : 2.0, vehicle ? 4.0 : 2.5, vehicle ? 0.01 : 0.005,
                                vehicle ? TextureStyle::kVehicle : TextureStyle::kPedestrian));
    }
    return pool[static_cast<std::size_t>(random_.integer(0, static_cast<int>(pool.size()) - 1))];
  }

  std::uint16_t nextInstanceId() {
    if (next_instance_id_ == 0xFFFF) throw OptionError("agents", "more than 65534 agents");
    return next_instance_id_++;
  }

  void addAgent(ObjectClass object_class, const LinearMotion& motion, bool moving) {
    const AgentSize size = object_class == ObjectClass::kVehicle ? vehicleSize() : pedestrianSize();
    addAgent(object_class, size, agentTexture(object_class), motion, moving);
  }

  void addAgent(ObjectClass object_class, const AgentSize& size, int texture,
                const LinearMotion& motion, bool moving) {
    const std::uint16_t id = nextInstanceId();
    world_.scene.objects.push_back(makeAgent(id, object_class, size, texture, motion));
    world_.agents.push_back({id, object_class, moving, motion.t_begin_ns, motion.t_end_ns});
  }

  bool insideRegion(const Eigen::Vector2d& xy, double margin) const {
    return (xy.array() >= region_min_.array() + margin).all() &&
           (xy.array() <= region_max_.array() - margin).all();
  }

  void addStaticAgents() {
    double travelled = 0.0;
    const double spacing_m = layout_.static_spacing_m / options_.parked_density;
    double next_at = random_.uniform(0.0, spacing_m);
    for (std::size_t i = 1; i < samples_.position.size(); ++i) {
      travelled += (samples_.position[i] - samples_.position[i - 1]).head<2>().norm();
      if (travelled < next_at) continue;
      next_at = travelled + spacing_m * random_.uniform(0.6, 1.4);
      tryPlaceStaticAgent(i);
    }
  }

  /// Places one parked car or standing person beside the path near `sample`, trying a few spots.
  void tryPlaceStaticAgent(std::size_t sample) {
    constexpr int kAttempts = 6;
    const ObjectClass object_class =
        options_.scene == SceneType::kIndoor ? ObjectClass::kPedestrian : randomAgentClass();
    const bool vehicle = object_class == ObjectClass::kVehicle;
    const AgentSize size = vehicle ? vehicleSize() : pedestrianSize();
    const double radius = std::hypot(0.5 * size.length, 0.5 * size.width) + 0.3;
    const double clearance = vehicle ? 1.0 : 0.8;  // from the camera path [m]
    const Eigen::Vector2d forward = samples_.forward_xy[sample];
    const Eigen::Vector2d left(-forward.y(), forward.x());
    for (int attempt = 0; attempt < kAttempts; ++attempt) {
      const double side = random_.chance(0.5) ? 1.0 : -1.0;
      const double lateral = vehicle ? random_.uniform(3.5, 8.0) : random_.uniform(1.5, 5.0);
      const Eigen::Vector2d xy = samples_.position[sample].head<2>() +
                                 forward * random_.uniform(2.0, 10.0) + left * side * lateral;
      if (samples_.distanceTo(xy) < clearance + radius || !insideRegion(xy, radius) ||
          overlapsFootprints(xy, Eigen::Vector2d::Constant(radius), 0.2)) {
        continue;
      }
      LinearMotion motion;
      motion.start_xy = xy;
      const double jitter = random_.uniform(-0.3, 0.3);
      const double reverse = random_.chance(0.5) ? M_PI : 0.0;
      motion.heading_rad = std::atan2(forward.y(), forward.x()) + jitter + reverse;
      motion.ground_z = world_.ground_z;
      motion.t_begin_ns = path_.range.begin;
      motion.t_end_ns = path_.range.end;
      addAgent(object_class, motion, false);
      footprints_.push_back({xy, Eigen::Vector2d::Constant(radius)});
      return;
    }
  }

  void addMovingAgents() {
    // An agent is in view for about half of its life (it enters and leaves the view, and some
    // plans fail near walls), and denser traffic hides more agents behind others: run more
    // agent slots than the level's target in view (factors measured with
    // bench/simulate_levels.sh).
    const int target = movingAgentTarget(options_.dynamic);
    const double occlusion = 1.0 - 0.02 * target;
    const int slots =
        static_cast<int>(std::ceil(layout_.slots_per_agent_in_view * target / occlusion));
    for (int slot = 0; slot < slots; ++slot) {
      TimeNs t = path_.range.begin + secondsToNs(random_.uniform(0.0, 2.0));
      while (t < path_.range.end) {
        const auto end = trySpawnMovingAgent(t);
        t = end ? *end + secondsToNs(random_.uniform(0.0, 0.5)) : t + kNsPerSecond;
      }
    }
  }

  /// Plans one agent crossing (or driving along) the camera's view around the middle of its
  /// life; returns the end of its life, or nullopt when no collision-free plan was found.
  std::optional<TimeNs> trySpawnMovingAgent(TimeNs t_begin) {
    for (int attempt = 0; attempt < 10; ++attempt) {
      const auto motion = planCrossing(t_begin);
      if (motion && isCollisionFree(motion->first, motion->second)) {
        addAgent(motion->second, motion->first, true);
        return motion->first.t_end_ns;
      }
    }
    return std::nullopt;
  }

  std::optional<std::pair<LinearMotion, ObjectClass>> planCrossing(TimeNs t_begin) {
    const ObjectClass object_class =
        options_.scene == SceneType::kIndoor ? ObjectClass::kPedestrian : randomAgentClass();
    const bool vehicle = object_class == ObjectClass::kVehicle;
    const double speed = vehicle
                             ? random_.uniform(layout_.vehicle_speed_min, layout_.vehicle_speed_max)
                             : random_.uniform(1.0, 2.0);
    const double distance =
        random_.uniform(layout_.crossing_distance_min, layout_.crossing_distance_max);
    const double half_view = distance * std::tan(0.5 * path_.horizontal_fov_rad);
    const double span = 2.0 * half_view * 1.3 + (vehicle ? 4.5 : 0.5);
    const double pause = random_.chance(vehicle ? 0.2 : 0.3) ? random_.uniform(1.0, 3.0) : 0.0;
    const double life_s = span / speed + pause + (pause > 0.0 ? 1.0 : 0.0);
    const TimeNs t_mid = std::min(path_.range.end, t_begin + secondsToNs(0.5 * life_s));

    const std::size_t k = samples_.indexAt(t_mid);
    const Eigen::Vector2d forward = samples_.forward_xy[k];
    const Eigen::Vector2d left(-forward.y(), forward.x());
    const bool crossing = random_.chance(0.6);
    const double view_heading = std::atan2(forward.y(), forward.x());
    double heading = view_heading, lateral = 0.0;
    if (crossing) {
      const double turn = random_.chance(0.5) ? 0.5 : -0.5;
      heading = view_heading + turn * M_PI + random_.uniform(-0.3, 0.3);
      lateral = random_.uniform(-0.3, 0.3) * half_view;
    } else {
      const double reverse = random_.chance(0.5) ? 0.0 : M_PI;
      heading = view_heading + reverse + random_.uniform(-0.15, 0.15);
      const double side = random_.chance(0.5) ? 1.0 : -1.0;
      lateral = side * random_.uniform(0.3, 0.8) * half_view;
    }
    const Eigen::Vector2d centre =
        samples_.position[k].head<2>() + forward * distance + left * lateral;
    const Eigen::Vector2d direction(std::cos(heading), std::sin(heading));

    LinearMotion motion;
    motion.heading_rad = heading;
    motion.speed_mps = speed;
    motion.ground_z = world_.ground_z;
    motion.t_begin_ns = t_begin;
    motion.pause_duration_s = pause;
    // Keep the path inside the world (rooms are small): clip it to the region around the centre.
    const auto inside = clipToRegion(centre, direction, 0.5 * span, 0.5);
    if (!inside || inside->second - inside->first < 2.0) return std::nullopt;
    const double length = inside->second - inside->first;
    const double clipped_life_s = length / speed + pause + (pause > 0.0 ? 1.0 : 0.0);
    motion.t_end_ns = std::min(path_.range.end, t_begin + secondsToNs(clipped_life_s));
    if (pause > 0.0) {
      motion.pause_begin_ns = t_begin + secondsToNs(0.5 * (clipped_life_s - pause));
    }
    motion.start_xy = centre + direction * inside->first;
    return std::make_pair(motion, object_class);
  }

  /// The part [s0, s1] of the segment centre + s * direction, |s| <= half_length, that lies
  /// inside the region shrunk by `margin`; nullopt when none does.
  std::optional<std::pair<double, double>> clipToRegion(const Eigen::Vector2d& centre,
                                                        const Eigen::Vector2d& direction,
                                                        double half_length, double margin) const {
    double s0 = -half_length, s1 = half_length;
    for (int axis = 0; axis < 2; ++axis) {
      const double lo = region_min_[axis] + margin, hi = region_max_[axis] - margin;
      if (std::abs(direction[axis]) < 1e-12) {
        if (centre[axis] < lo || centre[axis] > hi) return std::nullopt;
        continue;
      }
      double a = (lo - centre[axis]) / direction[axis], b = (hi - centre[axis]) / direction[axis];
      if (a > b) std::swap(a, b);
      s0 = std::max(s0, a);
      s1 = std::min(s1, b);
    }
    if (s0 >= s1) return std::nullopt;
    return std::make_pair(s0, s1);
  }

  // ------------------------------------------------------------ mover patterns (issue 14)
  //
  // Drawn from a random stream of their own after the level's agents, so that every level builds
  // the same world with or without a pattern.

  void addPatternGroups() {
    if (!options_.pattern.active()) return;
    const PatternSpec spec = patternSpec(options_.pattern);
    TimeNs t = path_.range.begin + secondsToNs(pattern_random_.uniform(0.0, 2.0));
    while (t < path_.range.end) {
      const auto end = trySpawnGroup(spec, t);
      t = end ? *end + secondsToNs(pattern_random_.uniform(1.0, 3.0)) : t + kNsPerSecond;
    }
  }

  /// Plans one group around the camera's view in the middle of its life; returns the end of its
  /// life, or nullopt when no plan kept clear of the camera.
  std::optional<TimeNs> trySpawnGroup(const PatternSpec& spec, TimeNs t_begin) {
    for (int attempt = 0; attempt < 10; ++attempt) {
      const auto members = planGroup(spec, t_begin);
      if (members.empty()) continue;
      const bool clear = std::all_of(members.begin(), members.end(), [&](const LinearMotion& m) {
        return keepsClearOfCamera(m, spec.size, spec.camera_clearance_m);
      });
      if (!clear) continue;
      for (const LinearMotion& motion : members) {
        addAgent(spec.object_class, spec.size, patternTexture(spec), motion, true);
      }
      return members.front().t_end_ns;
    }
    return std::nullopt;
  }

  /// The members' motions (one heading and speed for all), or none when the group's path leaves
  /// the world.
  std::vector<LinearMotion> planGroup(const PatternSpec& spec, TimeNs t_begin) {
    Random& random = pattern_random_;
    const double speed = random.uniform(spec.speed_min, spec.speed_max);
    const double distance = random.uniform(spec.distance_min, spec.distance_max);
    const bool crossing = random.chance(spec.crossing_share);
    const std::vector<Eigen::Vector2d> offsets = groupLayout(spec);  // (along, across) [m]
    double group_length = 0.0;
    for (const auto& o : offsets)
      group_length = std::max(group_length, 2.0 * std::abs(o.x()));
    group_length += spec.size.length;
    const double half_view = distance * std::tan(0.5 * path_.horizontal_fov_rad);
    // Crossing: from beyond one side of the view to beyond the other; along the view: past the
    // camera for 8 s (8-30 m).
    const double span =
        group_length + (crossing ? 2.0 * half_view * 1.3 : std::clamp(8.0 * speed, 8.0, 30.0));
    const TimeNs t_mid = std::min(path_.range.end, t_begin + secondsToNs(0.5 * span / speed));

    const std::size_t k = samples_.indexAt(t_mid);
    const Eigen::Vector2d forward = samples_.forward_xy[k];
    const Eigen::Vector2d left(-forward.y(), forward.x());
    const double view_heading = std::atan2(forward.y(), forward.x());
    const double side = random.chance(0.5) ? 1.0 : -1.0;
    double heading = view_heading;
    if (crossing) {
      heading = view_heading + side * 0.5 * M_PI + random.uniform(-0.15, 0.15);
    } else {
      const double reverse = random.chance(0.5) ? 0.0 : M_PI;
      heading = view_heading + reverse + random.uniform(-0.1, 0.1);
    }
    const Eigen::Vector2d centre =
        samples_.position[k].head<2>() +
        (crossing ? forward * distance + left * random.uniform(-0.2, 0.2) * half_view
                  : forward * random.uniform(6.0, 12.0) + left * side * distance);
    const Eigen::Vector2d direction(std::cos(heading), std::sin(heading));
    const auto inside = clipToRegion(centre, direction, 0.5 * span, 0.5 * group_length + 1.0);
    if (!inside || inside->second - inside->first < 0.6 * span) return {};

    const Eigen::Vector2d across(-direction.y(), direction.x());
    const double life_s = (inside->second - inside->first) / speed;
    std::vector<LinearMotion> members;
    for (const Eigen::Vector2d& offset : offsets) {
      LinearMotion motion;
      motion.heading_rad = heading;
      motion.speed_mps = speed;
      motion.ground_z = world_.ground_z;
      motion.t_begin_ns = t_begin;
      motion.t_end_ns = std::min(path_.range.end, t_begin + secondsToNs(life_s));
      motion.start_xy = centre + direction * (inside->first + offset.x()) + across * offset.y();
      members.push_back(motion);
    }
    return members;
  }

  /// Where the members stand in the group, relative to its centre: (along the motion, across it).
  std::vector<Eigen::Vector2d> groupLayout(const PatternSpec& spec) {
    Random& random = pattern_random_;
    const int n = spec.group_size;
    std::vector<Eigen::Vector2d> offsets;
    if (options_.pattern.pattern != MoverPattern::kCrowd) {
      // A line in one lane, bumper to bumper with one gap for all.
      const double pitch = spec.size.length + random.uniform(1.5, 3.0);
      for (int i = 0; i < n; ++i) {
        offsets.emplace_back((0.5 * (n - 1) - i) * pitch, random.uniform(-0.2, 0.2));
      }
      return offsets;
    }
    // People in a band, at least 0.7 m apart.
    const double half_length = std::max(1.0, 0.25 * n), half_width = 1.5;
    for (int i = 0; i < n; ++i) {
      Eigen::Vector2d o;
      for (int attempt = 0; attempt < 20; ++attempt) {
        o = {random.uniform(-half_length, half_length), random.uniform(-half_width, half_width)};
        const bool apart =
            std::all_of(offsets.begin(), offsets.end(),
                        [&](const Eigen::Vector2d& p) { return (p - o).norm() > 0.7; });
        if (apart) break;
      }
      offsets.push_back(o);
    }
    return offsets;
  }

  int patternTexture(const PatternSpec& spec) {
    constexpr std::size_t kPoolSize = 12;
    if (pattern_textures_.size() < kPoolSize) {
      pattern_textures_.push_back(addTexture(spec.texture_width_m, spec.texture_height_m,
                                             spec.texel_m, spec.texture_style, pattern_random_));
    }
    return pattern_textures_[static_cast<std::size_t>(
        pattern_random_.integer(0, static_cast<int>(pattern_textures_.size()) - 1))];
  }

  /// The box keeps at least `clearance` metres between its footprint and the camera.
  bool keepsClearOfCamera(const LinearMotion& motion, const AgentSize& size,
                          double clearance) const {
    const Eigen::Vector2d half(0.5 * size.length, 0.5 * size.width);
    for (TimeNs t = motion.t_begin_ns; t <= motion.t_end_ns; t += kPathSamplePeriodNs) {
      const Eigen::Vector2d camera = samples_.position[samples_.indexAt(t)].head<2>();
      const Eigen::Vector2d d = camera - motion.positionAt(t);
      const Eigen::Vector2d local(
          std::cos(motion.heading_rad) * d.x() + std::sin(motion.heading_rad) * d.y(),
          -std::sin(motion.heading_rad) * d.x() + std::cos(motion.heading_rad) * d.y());
      if ((local.cwiseAbs() - half).cwiseMax(0.0).norm() < clearance) return false;
    }
    return true;
  }

  /// Gives the "unlabelled" class to a share of the moving agents: one draw per moving agent in
  /// instance order, so a larger share relabels a superset and the world is otherwise unchanged.
  void relabelUnlabelledMovers() {
    for (std::size_t i = 0; i < world_.agents.size(); ++i) {
      AgentRecord& agent = world_.agents[i];
      if (!agent.ever_moving) continue;
      if (unlabelled_random_.uniform(0.0, 1.0) >= options_.unlabelled_share) continue;
      agent.object_class = ObjectClass::kUnlabelled;
      SceneObject& object = world_.scene.objects[i + 1];  // objects[0] is the static world
      if (object.instance_id != agent.instance_id) {
        throw std::logic_error("world builder: agent table and scene objects out of step");
      }
      object.object_class = ObjectClass::kUnlabelled;
    }
  }

  /// The agent keeps clear of the camera during its whole life.
  bool isCollisionFree(const LinearMotion& motion, ObjectClass object_class) const {
    const double min_distance = object_class == ObjectClass::kVehicle ? 3.5 : 1.5;  // [m]
    for (TimeNs t = motion.t_begin_ns; t <= motion.t_end_ns; t += kPathSamplePeriodNs) {
      const std::size_t k = samples_.indexAt(t);
      if ((samples_.position[k].head<2>() - motion.positionAt(t)).norm() < min_distance)
        return false;
    }
    return true;
  }

  const WorldOptions& options_;
  const CameraPath& path_;
  PathSamples samples_;
  SceneLayout layout_;
  Random random_;
  Random pattern_random_;
  Random unlabelled_random_;
  World world_;
  Eigen::Vector2d region_min_, region_max_;
  std::vector<std::pair<Eigen::Vector2d, Eigen::Vector2d>> footprints_;  ///< centre, half size
  std::vector<int> vehicle_textures_, pedestrian_textures_, pattern_textures_;
  /// A texture the static surfaces share (WorldOptions::texture_variety), as large as the largest.
  struct SharedTexture {
    int texture = 0;
    double width_m = 0.0, height_m = 0.0, texel_m = 0.0;
    TextureStyle style = TextureStyle::kGround;
    std::uint64_t seed = 0;
  };
  std::vector<SharedTexture> shared_textures_;
  std::map<std::pair<int, double>, std::vector<std::size_t>> shared_kinds_;  ///< style, texel
  std::uint16_t next_instance_id_ = 1;
};

}  // namespace

SceneType parseSceneType(const std::string& name) {
  if (name == "street") return SceneType::kStreet;
  if (name == "parking") return SceneType::kParking;
  if (name == "indoor") return SceneType::kIndoor;
  throw OptionError("scene", fmt::format("unknown scene '{}' (street|parking|indoor)", name));
}

DynamicLevel parseDynamicLevel(const std::string& name) {
  if (name == "none") return DynamicLevel::kNone;
  if (name == "low") return DynamicLevel::kLow;
  if (name == "mid") return DynamicLevel::kMid;
  if (name == "high") return DynamicLevel::kHigh;
  throw OptionError("dynamic", fmt::format("unknown dynamic level '{}' (none|low|mid|high)", name));
}

MoverPattern parseMoverPattern(const std::string& name) {
  if (name == "none") return MoverPattern::kNone;
  if (name == "bus") return MoverPattern::kBus;
  if (name == "convoy") return MoverPattern::kConvoy;
  if (name == "crowd") return MoverPattern::kCrowd;
  throw OptionError("dynamic-pattern",
                    fmt::format("unknown mover pattern '{}' (none|bus|convoy|crowd)", name));
}

std::string toString(MoverPattern pattern) {
  switch (pattern) {
    case MoverPattern::kNone:
      return "none";
    case MoverPattern::kBus:
      return "bus";
    case MoverPattern::kConvoy:
      return "convoy";
    case MoverPattern::kCrowd:
      return "crowd";
  }
  return "unknown";
}

std::string toString(SceneType scene) {
  switch (scene) {
    case SceneType::kStreet:
      return "street";
    case SceneType::kParking:
      return "parking";
    case SceneType::kIndoor:
      return "indoor";
  }
  return "unknown";
}

std::string toString(DynamicLevel level) {
  switch (level) {
    case DynamicLevel::kNone:
      return "none";
    case DynamicLevel::kLow:
      return "low";
    case DynamicLevel::kMid:
      return "mid";
    case DynamicLevel::kHigh:
      return "high";
  }
  return "unknown";
}

std::string toString(ObjectClass object_class) {
  switch (object_class) {
    case ObjectClass::kBackground:
      return "background";
    case ObjectClass::kVehicle:
      return "vehicle";
    case ObjectClass::kPedestrian:
      return "pedestrian";
    case ObjectClass::kUnlabelled:
      return "unlabelled";
  }
  return "unknown";
}

int movingAgentTarget(DynamicLevel level) {
  switch (level) {
    case DynamicLevel::kNone:
      return 0;
    case DynamicLevel::kLow:
      return 2;
    case DynamicLevel::kMid:
      return 5;
    case DynamicLevel::kHigh:
      return 10;
  }
  return 0;
}

void MoverPatternOptions::validate() const {
  if (!active()) {
    // Settings of a pattern without one are a mistake, not something to ignore.
    if (group_size != 0) throw OptionError("pattern-size", "needs --dynamic-pattern");
    if (min_distance_m != 0.0 || max_distance_m != 0.0) {
      throw OptionError("pattern-distance", "needs --dynamic-pattern");
    }
    if (slow) throw OptionError("slow-movers", "needs --dynamic-pattern");
  }
  if (group_size < 0 || group_size > 50) {
    throw OptionError("pattern-size", "must be in [0, 50] (0 = the pattern's default)");
  }
  const bool default_distance = min_distance_m == 0.0 && max_distance_m == 0.0;
  if (!default_distance &&
      !(min_distance_m >= 1.0 && min_distance_m <= max_distance_m && max_distance_m <= 50.0)) {
    throw OptionError("pattern-distance",
                      fmt::format("expected MIN,MAX with 1 <= MIN <= MAX <= 50 m, got {},{}",
                                  min_distance_m, max_distance_m));
  }
}

void WorldOptions::validate() const {
  if (!(ground_clearance_m > 0.0)) throw OptionError("ground_clearance_m", "must be > 0");
  if (!(texel_scale > 0.0)) throw OptionError("texel_scale", "must be > 0");
  if (!(parked_density > 0.0 && parked_density <= 10.0)) {
    throw OptionError("parked-density", fmt::format("must be in (0, 10], got {}", parked_density));
  }
  if (!(background_contrast > 0.0 && background_contrast <= 1.0)) {
    throw OptionError("background-contrast",
                      fmt::format("must be in (0, 1], got {}", background_contrast));
  }
  if (texture_variety < 0 || texture_variety > 1000) {
    throw OptionError(
        "texture-variety",
        fmt::format("must be in [0, 1000] (0: every surface its own), got {}", texture_variety));
  }
  pattern.validate();
  if (scene == SceneType::kIndoor &&
      (pattern.pattern == MoverPattern::kBus || pattern.pattern == MoverPattern::kConvoy)) {
    throw OptionError("dynamic-pattern", fmt::format("pattern '{}' needs a street or parking "
                                                     "scene (indoor: none or crowd)",
                                                     toString(pattern.pattern)));
  }
  if (!(unlabelled_share >= 0.0 && unlabelled_share <= 1.0)) {
    throw OptionError("unlabelled", fmt::format("must be in [0, 1], got {}", unlabelled_share));
  }
}

World buildWorldIn(const WorldOptions& static_options, const CameraPath& static_path,
                   const WorldOptions& options, const CameraPath& camera_path,
                   const ReusedWorldHint& hint) {
  static_options.validate();
  options.validate();
  WorldBuilder static_builder(static_options, static_path);
  static_builder.buildStatic();
  WorldBuilder builder(options, camera_path);
  builder.adoptStaticWorld(std::move(static_builder), hint);
  return builder.buildAgents();
}

std::uint64_t staticWorldFingerprint(const World& world) {
  std::uint64_t hash = mix64(world.scene.objects.front().quads.size());
  const auto add = [&](double value) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &value, sizeof(bits));
    hash = mix64(hash ^ bits);
  };
  add(world.ground_z);
  std::set<int> textures;
  for (const Quad& quad : world.scene.objects.front().quads) {
    for (const Eigen::Vector3d& v : {quad.origin, quad.edge_u, quad.edge_v})
      for (int k = 0; k < 3; ++k)
        add(v[k]);
    add(quad.texture_offset_m.x());
    add(quad.texture_offset_m.y());
    add(static_cast<double>(quad.texture));
    textures.insert(quad.texture);
  }
  for (const int index : textures) {
    const Texture& texture = world.scene.textures.at(static_cast<std::size_t>(index));
    add(texture.texelSizeM());
    const cv::Mat image =
        texture.image().isContinuous() ? texture.image() : texture.image().clone();
    const std::size_t bytes = image.total() * image.elemSize();
    for (std::size_t i = 0; i + 8 <= bytes; i += 8) {
      std::uint64_t word = 0;
      std::memcpy(&word, image.data + i, sizeof(word));
      hash = mix64(hash ^ word);
    }
  }
  return hash;
}

World buildWorld(const WorldOptions& options, const CameraPath& camera_path) {
  options.validate();
  return WorldBuilder(options, camera_path).build();
}

}  // namespace superdyna::sim
