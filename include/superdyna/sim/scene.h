#pragma once
// The synthetic world: textured planar quads grouped into objects. The static world is one or
// more objects with instance id 0; every agent (vehicle, pedestrian) is an object with its own
// instance id and a pose that changes with time.

#include <cstdint>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/core/geometry.h"
#include "superdyna/core/time.h"
#include "superdyna/sim/texture.h"

namespace superdyna::sim {

/// Semantic class of an object, as the segmentation masks and the instance table report it.
/// kUnlabelled: a mover of a class the masks do not label (it looks like background to them); it
/// is listed in the instance tables only.
enum class ObjectClass { kBackground, kVehicle, kPedestrian, kUnlabelled };
std::string toString(ObjectClass object_class);

/// A planar rectangle origin + a * edge_u + b * edge_v, (a, b) in [0, 1]^2, in its object's
/// frame. Texture coordinates are metres along the edges plus `texture_offset_m`, so one texture
/// can cover several quads without visible repetition.
struct Quad {
  Eigen::Vector3d origin = Eigen::Vector3d::Zero();
  Eigen::Vector3d edge_u = Eigen::Vector3d::UnitX();
  Eigen::Vector3d edge_v = Eigen::Vector3d::UnitY();
  int texture = 0;  ///< Index into Scene::textures.
  Eigen::Vector2d texture_offset_m = Eigen::Vector2d::Zero();
};

/// Pose of an object at a time; nullopt while the object is not in the world (before it enters,
/// after it leaves).
using PoseTrack = std::function<std::optional<SE3d>(TimeNs t_ns)>;

struct SceneObject {
  std::uint16_t instance_id = 0;  ///< 0 for the static world, else unique per agent.
  ObjectClass object_class = ObjectClass::kBackground;
  std::vector<Quad> quads;  ///< In the object's own frame.
  PoseTrack T_w_o;          ///< Object-to-world pose over time; empty means identity, always.
  /// Whether the object moves at time t (moving agents: true while their speed > 0).
  std::function<bool(TimeNs t_ns)> is_moving;
};

struct Scene {
  std::vector<Texture> textures;
  std::vector<SceneObject> objects;
};

}  // namespace superdyna::sim
