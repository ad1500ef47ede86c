#include "eval_test_data.h"

#include "superdyna/io/trajectory_io.h"

namespace superdyna::eval::testdata {

Trajectory readSubsampled(const std::filesystem::path& file, std::size_t step) {
  const Trajectory all = io::readTrajectory(file);
  Trajectory every_step;
  for (std::size_t i = 0; i < all.size(); i += step)
    every_step.push_back(all[i]);
  return every_step;
}

Sim3d randomSim3(std::mt19937& rng, bool unit_scale) {
  std::uniform_real_distribution<double> unit(-1.0, 1.0);
  std::uniform_real_distribution<double> log_scale(std::log(0.3), std::log(3.0));
  Sim3d T;
  const Eigen::Vector3d axis = Eigen::Vector3d(unit(rng), unit(rng), unit(rng)).normalized();
  T.R = expSO3(axis * 3.0 * std::abs(unit(rng)));
  T.t = 10.0 * Eigen::Vector3d(unit(rng), unit(rng), unit(rng));
  T.s = unit_scale ? 1.0 : std::exp(log_scale(rng));
  return T;
}

Trajectory transformed(const Sim3d& T, const Trajectory& trajectory) {
  Trajectory out;
  for (const StampedPose& pose : trajectory)
    out.push_back({pose.t_ns, T * pose.T_w_x});
  return out;
}

Trajectory perturbed(const Trajectory& trajectory, double sigma_m, double sigma_rad,
                     std::uint32_t seed) {
  std::mt19937 rng(seed);
  std::normal_distribution<double> position_noise(0.0, sigma_m);
  std::normal_distribution<double> angle_noise(0.0, sigma_rad);
  Trajectory out;
  for (const StampedPose& pose : trajectory) {
    const Eigen::Vector3d dp(position_noise(rng), position_noise(rng), position_noise(rng));
    const Eigen::Vector3d dr(angle_noise(rng), angle_noise(rng), angle_noise(rng));
    out.push_back(
        {pose.t_ns, SE3d(Eigen::Matrix3d(pose.T_w_x.rotation() * expSO3(dr)), pose.T_w_x.t + dp)});
  }
  return out;
}

}  // namespace superdyna::eval::testdata
