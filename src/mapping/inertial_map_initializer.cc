#include "superdyna/mapping/inertial_map_initializer.h"

#include <fmt/format.h>

#include <algorithm>
#include <cmath>
#include <optional>
#include <stdexcept>
#include <vector>

#include "superdyna/core/error.h"
#include "superdyna/mapping/keyframe_preintegration.h"

namespace superdyna::mapping {

void InertialMapInitOptions::validate() const {
  if (min_keyframes < 3) throw OptionError("inertial_init.min_keyframes", "must be >= 3");
  const auto positive = [](double value, const char* name) {
    if (!(value > 0.0) || !std::isfinite(value)) throw OptionError(name, "must be > 0");
  };
  positive(min_duration_s, "inertial_init.min_duration_s");
  positive(gyro_bias_prior_sigma, "inertial_init.gyro_bias_prior_sigma");
  positive(accel_bias_prior_sigma, "inertial_init.accel_bias_prior_sigma");
  positive(min_scale_excitation, "inertial_init.min_scale_excitation");
  positive(unexcited_accel_bias_prior_sigma, "inertial_init.unexcited_accel_bias_prior_sigma");
  if (!(min_rotation_for_accel_bias_deg >= 0.0)) {
    throw OptionError("inertial_init.min_rotation_for_accel_bias_deg", "must be >= 0");
  }
  if (max_iterations < 1) throw OptionError("inertial_init.max_iterations", "must be >= 1");
  if (reintegration_rounds < 0) {
    throw OptionError("inertial_init.reintegration_rounds", "must be >= 0");
  }
}

namespace {

/// A monocular map has median scene depth 1 (two-view initialisation): a smaller scale than this
/// would put the scene within 10 cm of the camera. As ORB-SLAM3, such an estimate (the solver's
/// answer when the visual trajectory and the IMU disagree, e.g. over a short smooth window) is
/// refused and the initialisation retried at the next keyframe.
constexpr double kMinScale = 0.1;

/// The latest run of keyframes linked to their predecessors with usable IMU samples, in time
/// order, with the preintegrations between them (at zero bias: the first guess).
struct KeyFrameChain {
  std::vector<map::KeyFrameId> ids;
  std::vector<TimeNs> t_ns;
  std::vector<SE3d> T_w_b;
  std::vector<imu::Preintegration> preintegrations;  ///< ids.size() - 1 entries.
};

KeyFrameChain latestChain(const map::Map& map, const imu::ImuNoise& noise) {
  KeyFrameChain reversed;  // built from the newest backwards
  std::vector<std::optional<imu::Preintegration>> gaps;
  map::KeyFrameId id = map.newestKeyFrame();
  while (id != map::kNoKeyFrame) {
    std::optional<map::KeyFrame> kf = map.keyFrame(id);
    reversed.ids.push_back(id);
    reversed.t_ns.push_back(kf->t_ns);
    reversed.T_w_b.push_back(kf->T_w_b);
    const std::optional<SE3d> previous_pose = map.keyFramePose(kf->previous);
    if (!previous_pose) break;
    TimeNs t_previous_ns = 0;
    map.readKeyFrame(kf->previous, [&](const map::KeyFrame& p) { t_previous_ns = p.t_ns; });
    std::optional<imu::Preintegration> pre =
        preintegrateFromPrevious(*kf, t_previous_ns, imu::Bias{}, noise);
    if (!pre) break;
    reversed.preintegrations.push_back(std::move(*pre));
    id = kf->previous;
  }
  KeyFrameChain chain;
  chain.ids.assign(reversed.ids.rbegin(), reversed.ids.rend());
  chain.t_ns.assign(reversed.t_ns.rbegin(), reversed.t_ns.rend());
  chain.T_w_b.assign(reversed.T_w_b.rbegin(), reversed.T_w_b.rend());
  chain.preintegrations.assign(reversed.preintegrations.rbegin(), reversed.preintegrations.rend());
  return chain;
}

/// RMS deviation of the keyframe intervals' mean specific force, rotated into the world frame by
/// the keyframe orientations, from its mean [m/s^2]. Gravity is the same in every interval, so
/// this measures how much the true (metric) acceleration varies: how well the motion excites the
/// scale. Unlike the visual accelerations it needs no metric map; rotations are scale-free.
double specificForceExcitation(const KeyFrameChain& chain, const SE3d& T_b_i) {
  std::vector<Eigen::Vector3d> forces;
  for (std::size_t k = 0; k < chain.preintegrations.size(); ++k) {
    const imu::Preintegration& pre = chain.preintegrations[k];
    if (!(pre.deltaTime() > 0.0)) continue;
    const Eigen::Matrix3d R_w_i = chain.T_w_b[k].rotation() * T_b_i.rotation();
    forces.push_back(R_w_i * pre.deltaVelocity() / pre.deltaTime());
  }
  if (forces.size() < 2) return 0.0;
  Eigen::Vector3d mean = Eigen::Vector3d::Zero();
  for (const auto& f : forces)
    mean += f / static_cast<double>(forces.size());
  double sum = 0.0;
  for (const auto& f : forces)
    sum += (f - mean).squaredNorm();
  return std::sqrt(sum / static_cast<double>(forces.size()));
}

/// Largest rotation angle of a keyframe relative to the first [deg].
double largestRotationDeg(const KeyFrameChain& chain) {
  double largest = 0.0;
  for (const SE3d& T : chain.T_w_b)
    largest = std::max(largest, chain.T_w_b.front().q.angularDistance(T.q));
  return largest * 180.0 / M_PI;
}

void applyToMap(map::Map& map, const KeyFrameChain& chain, const InertialMapInitResult& result) {
  const map::Map::UpdateLock update = map.updateLock();  // one map update
  map.transformWorld(result.T_new_old);
  const imu::Bias& bias = result.estimate.bias;
  for (const map::KeyFrameId id : map.keyFrameIds()) {
    map.setKeyFrameInertialState(id, Eigen::Vector3d::Zero(), bias.bg, bias.ba);
  }
  for (std::size_t k = 0; k < chain.ids.size(); ++k) {
    map.setKeyFrameInertialState(chain.ids[k], result.estimate.R_w_v * result.estimate.v_v[k],
                                 bias.bg, bias.ba);
  }
}

}  // namespace

InertialMapInitResult initializeInertialMap(map::Map& map, const SE3d& T_b_i,
                                            const imu::ImuNoise& noise,
                                            const InertialMapInitOptions& options) {
  options.validate();
  noise.validate();
  InertialMapInitResult result;
  KeyFrameChain chain = latestChain(map, noise);
  result.keyframes = static_cast<int>(chain.ids.size());
  result.duration_s = chain.ids.empty() ? 0.0 : nsToSeconds(chain.t_ns.back() - chain.t_ns.front());
  if (result.keyframes < options.min_keyframes) {
    result.reason =
        fmt::format("{} linked keyframes, {} needed", result.keyframes, options.min_keyframes);
    return result;
  }
  if (result.duration_s < options.min_duration_s) {
    result.reason = fmt::format("keyframes span {:.2f} s, {:.2f} s needed", result.duration_s,
                                options.min_duration_s);
    return result;
  }
  if (options.estimate_scale) {
    const double excitation = specificForceExcitation(chain, T_b_i);
    if (excitation < options.min_scale_excitation) {
      result.reason =
          fmt::format("acceleration excitation {:.3f} below {:.3f} m/s^2: scale unobservable",
                      excitation, options.min_scale_excitation);
      return result;
    }
  }

  imu::InertialInitInput input;
  for (const SE3d& T_w_b : chain.T_w_b)
    input.T_v_b.push_back(T_w_b * T_b_i);
  input.preintegrations = std::move(chain.preintegrations);
  imu::InertialInitOptions init;
  init.estimate_scale = options.estimate_scale;
  init.gyro_bias_prior_sigma = options.gyro_bias_prior_sigma;
  result.rotation_deg = largestRotationDeg(chain);
  result.accel_bias_prior_sigma =
      result.rotation_deg < options.min_rotation_for_accel_bias_deg
          ? std::min(options.accel_bias_prior_sigma, options.unexcited_accel_bias_prior_sigma)
          : options.accel_bias_prior_sigma;
  init.accel_bias_prior_sigma = result.accel_bias_prior_sigma;
  init.max_iterations = options.max_iterations;
  init.reintegration_rounds = options.reintegration_rounds;
  try {
    result.estimate = imu::initializeInertial(input, init);
  } catch (const std::runtime_error& e) {
    result.reason = e.what();
    return result;
  }
  if (!std::isfinite(result.estimate.scale) || !(result.estimate.scale > 0.0)) {
    result.reason = "non-positive scale estimate";
    return result;
  }
  if (options.estimate_scale && result.estimate.scale < kMinScale) {
    result.reason = fmt::format(
        "scale estimate {:.3g} below {:.3g}: the visual motion does not "
        "fit the IMU",
        result.estimate.scale, kMinScale);
    return result;
  }
  result.T_new_old.s = result.estimate.scale;
  result.T_new_old.R = result.estimate.R_w_v;
  result.T_new_old.t.setZero();
  applyToMap(map, chain, result);
  result.applied = true;
  return result;
}

}  // namespace superdyna::mapping
