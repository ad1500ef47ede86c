#include "superdyna/sim/agents.h"

#include <algorithm>
#include <cmath>

namespace superdyna::sim {

namespace {

/// Seconds over which an agent slows down to a pause or speeds up after it.
constexpr double kRampSeconds = 0.5;

/// Integral of a cosine speed ramp from 1 to 0 over kRampSeconds, evaluated after `s` seconds
/// (distance covered at unit cruise speed).
double rampDownDistance(double s) {
  const double x = std::clamp(s, 0.0, kRampSeconds);
  return 0.5 * x + 0.5 * kRampSeconds / M_PI * std::sin(M_PI * x / kRampSeconds);
}

double rampDownSpeed(double s) {
  const double x = std::clamp(s, 0.0, kRampSeconds);
  return 0.5 * (1.0 + std::cos(M_PI * x / kRampSeconds));
}

}  // namespace

AgentSize vehicleSize() {
  return {4.5, 1.8, 1.5};
}
AgentSize pedestrianSize() {
  return {0.35, 0.55, 1.75};
}
AgentSize busSize() {
  return {12.0, 2.55, 3.2};
}

std::vector<Quad> makeBoxQuads(const AgentSize& size, int texture) {
  const double hl = 0.5 * size.length, hw = 0.5 * size.width, h = size.height;
  const Eigen::Vector3d x = Eigen::Vector3d::UnitX() * size.length;
  const Eigen::Vector3d y = Eigen::Vector3d::UnitY() * size.width;
  const Eigen::Vector3d down = -Eigen::Vector3d::UnitZ() * h;
  const double perimeter_offset = size.length + size.width;
  std::vector<Quad> quads;
  // Sides start at the top edge with edge_v pointing down (textures have their top at row 0) and
  // wind around the box so the texture runs continuously along its perimeter.
  quads.push_back({{-hl, -hw, h}, x, down, texture, {0.0, 0.0}});              // right
  quads.push_back({{hl, -hw, h}, y, down, texture, {size.length, 0.0}});       // front
  quads.push_back({{hl, hw, h}, -x, down, texture, {perimeter_offset, 0.0}});  // left
  quads.push_back(
      {{-hl, hw, h}, -y, down, texture, {perimeter_offset + size.length, 0.0}});  // rear
  quads.push_back({{-hl, -hw, h}, x, y, texture, {0.0, h + 0.5}});                // roof / head
  return quads;
}

double LinearMotion::distanceAt(TimeNs t_ns) const {
  const double t = nsToSeconds(std::clamp(t_ns, t_begin_ns, t_end_ns) - t_begin_ns);
  if (pause_duration_s <= 0.0 || speed_mps <= 0.0) return speed_mps * t;
  // Cruise until the ramp-down starts, ramp down, stand, ramp up, cruise.
  const double ramp_start = nsToSeconds(pause_begin_ns - t_begin_ns) - kRampSeconds;
  const double stand_end = ramp_start + kRampSeconds + pause_duration_s;
  if (t <= ramp_start) return speed_mps * t;
  double d = speed_mps * ramp_start + speed_mps * rampDownDistance(t - ramp_start);
  if (t <= stand_end) return d;
  const double s_up = std::min(t - stand_end, kRampSeconds);
  d += speed_mps * (s_up - rampDownDistance(s_up));  // ramp up mirrors the ramp down
  return d + speed_mps * std::max(0.0, t - stand_end - kRampSeconds);
}

double LinearMotion::speedAt(TimeNs t_ns) const {
  if (!exists(t_ns)) return 0.0;
  if (pause_duration_s <= 0.0) return speed_mps;
  const double t = nsToSeconds(t_ns - t_begin_ns);
  const double ramp_start = nsToSeconds(pause_begin_ns - t_begin_ns) - kRampSeconds;
  const double stand_end = ramp_start + kRampSeconds + pause_duration_s;
  if (t <= ramp_start) return speed_mps;
  if (t <= ramp_start + kRampSeconds) return speed_mps * rampDownSpeed(t - ramp_start);
  if (t <= stand_end) return 0.0;
  if (t <= stand_end + kRampSeconds) return speed_mps * (1.0 - rampDownSpeed(t - stand_end));
  return speed_mps;
}

Eigen::Vector2d LinearMotion::positionAt(TimeNs t_ns) const {
  const Eigen::Vector2d direction(std::cos(heading_rad), std::sin(heading_rad));
  return start_xy + distanceAt(t_ns) * direction;
}

SE3d LinearMotion::poseAt(TimeNs t_ns) const {
  const Eigen::Vector2d xy = positionAt(t_ns);
  return SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(heading_rad, Eigen::Vector3d::UnitZ())),
              Eigen::Vector3d(xy.x(), xy.y(), ground_z));
}

SceneObject makeAgent(std::uint16_t instance_id, ObjectClass object_class, const AgentSize& size,
                      int texture, const LinearMotion& motion) {
  SceneObject object;
  object.instance_id = instance_id;
  object.object_class = object_class;
  object.quads = makeBoxQuads(size, texture);
  object.T_w_o = [motion](TimeNs t_ns) -> std::optional<SE3d> {
    if (!motion.exists(t_ns)) return std::nullopt;
    return motion.poseAt(t_ns);
  };
  object.is_moving = [motion](TimeNs t_ns) { return motion.speedAt(t_ns) > 1e-3; };
  return object;
}

}  // namespace superdyna::sim
