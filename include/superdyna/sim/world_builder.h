#pragma once
// Builds the synthetic world around a camera path: static textured geometry (ground, building
// facades or room walls, clutter), static movable agents (parked cars, standing people) along the
// path, and moving agents that cross or follow the camera's view so that, on average, the dynamic
// level's number of moving agents is in view.

#include <cstdint>
#include <functional>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

#include "superdyna/sim/scene.h"

namespace superdyna::sim {

enum class SceneType { kStreet, kParking, kIndoor };
enum class DynamicLevel { kNone, kLow, kMid, kHigh };
/// Groups of movers that fill much of the view and move coherently, the movers that defeat
/// RANSAC and robust kernels (issue 14), added on top of the level's scattered traffic:
/// bus: one 12 m bus (vehicle class) crossing the view or driving along it a few metres away;
/// convoy: a line of cars at the same speed; crowd: people walking the same way in a band.
enum class MoverPattern { kNone, kBus, kConvoy, kCrowd };

SceneType parseSceneType(const std::string& name);        ///< street|parking|indoor
DynamicLevel parseDynamicLevel(const std::string& name);  ///< none|low|mid|high
MoverPattern parseMoverPattern(const std::string& name);  ///< none|bus|convoy|crowd
std::string toString(SceneType scene);
std::string toString(DynamicLevel level);
std::string toString(MoverPattern pattern);

/// Moving agents in view at a time that a level aims for: none 0, low 2, mid 5, high 10.
int movingAgentTarget(DynamicLevel level);

/// How a mover pattern's groups are made. One group passes at a time: each is planned around the
/// camera's view at the middle of its life, the next one starts 1-3 s after it has gone.
struct MoverPatternOptions {
  MoverPattern pattern = MoverPattern::kNone;
  /// Agents per group; 0 = the pattern's default (bus 1, convoy 4, crowd 10).
  int group_size = 0;
  /// Range of the group's distance from the camera [m]: ahead of it for a group crossing the view,
  /// beside it for one moving along the view. Zeros = the pattern's default (bus 3-6 m, convoy 4-7
  /// m, crowd 2-5 m).
  double min_distance_m = 0.0;
  double max_distance_m = 0.0;
  /// Slow movers, whose image motion between frames stays within the robust kernels: vehicles at
  /// 0.5-1.5 m/s (else 2-5 m/s), people at 0.3-0.6 m/s (else 1.0-1.6 m/s).
  bool slow = false;

  bool active() const { return pattern != MoverPattern::kNone; }
  void validate() const;
};

struct WorldOptions {
  SceneType scene = SceneType::kStreet;
  DynamicLevel dynamic = DynamicLevel::kMid;
  MoverPatternOptions pattern;
  /// Share of the moving agents (level traffic and pattern groups) whose class is "unlabelled":
  /// they are in the instance tables but not in the instance masks, as movers a segmenter does not
  /// know. Drawn per agent from a stream of its own: the world is the same whatever the share.
  double unlabelled_share = 0.0;
  std::uint64_t seed = 1;
  /// The ground plane lies this far below the lowest camera position [m].
  double ground_clearance_m = 1.2;
  /// Multiplies every texel size: > 1 gives coarser, faster-to-generate textures.
  double texel_scale = 1.0;
  /// Contrast of the static world's textures (ground, walls, clutter; not the agents, parked or
  /// moving) relative to their usual look, in (0, 1]: below 1 a weakly textured background, on
  /// which parked cars and standing people hold a larger share of the features.
  double background_contrast = 1.0;
  /// Places for parked cars and standing people per metre of path relative to the scene's usual
  /// number, in (0, 10]: a full parking lot (places overlapping an earlier agent are skipped,
  /// so 4 gives about 2.5 times as many agents). The moving agents are drawn after them from the
  /// same stream, so another density gives other movers too.
  double parked_density = 1.0;
  /// Repeated textures, for testing place recognition against perceptual aliasing: 0 gives every
  /// static surface (ground tile, wall panel, block face) a texture of its own; N > 0 makes the
  /// static surfaces of each kind (texture style and texel size) share N textures, so different
  /// places look alike (each surface shows the top-left of its shared texture). The layout and the
  /// agents are those of the same seed with 0.
  int texture_variety = 0;
  /// Real photos (grayscale) to build textures from instead of procedural ones; may be empty.
  std::vector<cv::Mat> photos;

  void validate() const;
};

/// What the builder needs to know of the camera: its pose over the sequence and its field of view.
struct CameraPath {
  std::function<SE3d(TimeNs)> T_w_c;
  TimeRange range;
  double horizontal_fov_rad = 1.4;
};

/// One moving or static agent, as listed in the instance table.
struct AgentRecord {
  std::uint16_t instance_id = 0;
  ObjectClass object_class = ObjectClass::kVehicle;
  bool ever_moving = false;
  TimeNs t_begin_ns = 0;
  TimeNs t_end_ns = 0;
};

struct World {
  Scene scene;
  std::vector<AgentRecord> agents;
  double ground_z = 0.0;
};

/// Deterministic for given options and camera path.
World buildWorld(const WorldOptions& options, const CameraPath& camera_path);

/// What buildWorldIn's error says about the times of a reused world: `origin_ns` is the camera
/// path's time that --start counts from, `fits` a part of the trajectory that fits (the one the
/// reused world was built around, as --start and --duration).
struct ReusedWorldHint {
  TimeNs origin_ns = 0;
  std::string fits;
};

/// A second world in the static scene of another (simulate --world-of): the static world (ground,
/// room or buildings, clutter) is the one buildWorld(static_options, static_path) builds; the
/// agents are drawn around `camera_path` from options.seed (options.scene must equal
/// static_options.scene). OptionError when camera_path leaves that world or runs into a block,
/// naming the time (since hint.origin_ns) and the part that fits (hint.fits).
World buildWorldIn(const WorldOptions& static_options, const CameraPath& static_path,
                   const WorldOptions& options, const CameraPath& camera_path,
                   const ReusedWorldHint& hint = {});

/// A hash of the static world (instance 0's quads, the pixels of their textures, the ground
/// height): equal for equal static worlds.
std::uint64_t staticWorldFingerprint(const World& world);

}  // namespace superdyna::sim
