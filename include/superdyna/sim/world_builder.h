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

SceneType parseSceneType(const std::string& name);        ///< street|parking|indoor
DynamicLevel parseDynamicLevel(const std::string& name);  ///< none|low|mid|high
std::string toString(SceneType scene);
std::string toString(DynamicLevel level);

/// Moving agents in view at a time that a level aims for: none 0, low 2, mid 5, high 10.
int movingAgentTarget(DynamicLevel level);

struct WorldOptions {
  SceneType scene = SceneType::kStreet;
  DynamicLevel dynamic = DynamicLevel::kMid;
  std::uint64_t seed = 1;
  /// The ground plane lies this far below the lowest camera position [m].
  double ground_clearance_m = 1.2;
  /// Multiplies every texel size: > 1 gives coarser, faster-to-generate textures.
  double texel_scale = 1.0;
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

}  // namespace superdyna::sim
