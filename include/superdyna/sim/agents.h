#pragma once
// Movable agents of the synthetic world: vehicles and pedestrians as textured boxes standing on
// the ground, either static (parked, standing) or moving along a straight path at their own speed,
// optionally pausing on the way (so that "movable" and "moving" differ over time too).

#include <cstdint>
#include <optional>

#include "superdyna/sim/scene.h"

namespace superdyna::sim {

/// Box dimensions [m]: length along the agent's x (heading), width along y, height along z.
struct AgentSize {
  double length = 4.5;
  double width = 1.8;
  double height = 1.5;
};

AgentSize vehicleSize();
AgentSize pedestrianSize();
AgentSize busSize();  ///< 12 x 2.55 x 3.2 m, the bus mover pattern's body.

/// Textured box with its origin at the centre of its footprint on the ground; 5 faces (no
/// bottom). Faces share `texture`, each with its own texture offset.
std::vector<Quad> makeBoxQuads(const AgentSize& size, int texture);

/// Straight-line motion on the ground plane z = ground_z with heading `heading_rad` (about +z).
/// The agent exists during [t_begin_ns, t_end_ns]; it moves at `speed_mps` except for an optional
/// pause, entered and left with smooth speed ramps.
struct LinearMotion {
  Eigen::Vector2d start_xy = Eigen::Vector2d::Zero();  ///< Position at t_begin [m].
  double heading_rad = 0.0;
  double speed_mps = 0.0;  ///< Cruise speed; 0 for a static agent.
  double ground_z = 0.0;
  TimeNs t_begin_ns = 0;
  TimeNs t_end_ns = 0;
  /// Optional pause: stands still from pause_begin for pause_duration_s (0 = no pause).
  TimeNs pause_begin_ns = 0;
  double pause_duration_s = 0.0;

  bool exists(TimeNs t_ns) const { return t_ns >= t_begin_ns && t_ns <= t_end_ns; }
  /// Distance travelled since t_begin [m].
  double distanceAt(TimeNs t_ns) const;
  /// Speed at t [m/s] (0 while paused, ramps at pause edges).
  double speedAt(TimeNs t_ns) const;
  Eigen::Vector2d positionAt(TimeNs t_ns) const;
  SE3d poseAt(TimeNs t_ns) const;
};

/// A scene object for an agent following `motion`.
SceneObject makeAgent(std::uint16_t instance_id, ObjectClass object_class, const AgentSize& size,
                      int texture, const LinearMotion& motion);

}  // namespace superdyna::sim
