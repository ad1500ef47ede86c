#pragma once
// Trajectories shared by the eval tests: real EuRoC ground truth (subsampled to keep tests fast)
// and controlled transformations and perturbations of it.

#include <cstdint>
#include <filesystem>
#include <random>

#include "superdyna/core/geometry.h"
#include "superdyna/core/trajectory.h"

namespace superdyna::eval::testdata {

inline constexpr const char* kMh01 = "data/trajectories/euroc/MH_01_easy.txt";

/// Every `step`-th pose of the trajectory in `file`.
Trajectory readSubsampled(const std::filesystem::path& file, std::size_t step);

/// A random similarity: rotation of any angle, translation in [-10, 10] m per axis, scale in
/// [0.3, 3] (or exactly 1 when `unit_scale`).
Sim3d randomSim3(std::mt19937& rng, bool unit_scale);

/// Every pose mapped by `T` (positions s R p + t, rotations R R_p).
Trajectory transformed(const Sim3d& T, const Trajectory& trajectory);

/// Every pose with Gaussian noise: positions sigma_m per axis, rotations a random rotation vector
/// with sigma_rad per axis.
Trajectory perturbed(const Trajectory& trajectory, double sigma_m, double sigma_rad,
                     std::uint32_t seed);

}  // namespace superdyna::eval::testdata
