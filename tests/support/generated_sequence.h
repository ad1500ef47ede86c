#pragma once
// Synthetic sequences shared by the tests of one test process: generated on first use into a
// scratch folder, reused by every later test, removed when the process ends.

#include <cstdint>
#include <filesystem>
#include <string>

#include "superdyna/sensors/frame_bundle.h"
#include "superdyna/sim/sequence_generator.h"

namespace superdyna::test {

/// Generates the sequence `options` describes (output_dir and overwrite are set here) into a
/// scratch folder named `name` the first time `name` is asked for, and returns the sequence
/// folder; later calls with the same name return it without generating again.
const std::filesystem::path& generatedSequence(const std::string& name,
                                               sim::SimulationOptions options);

/// Options of a procedural flight of `duration_s` through `scene` with `dynamic` agents (the
/// simulator's defaults otherwise), for generatedSequence().
sim::SimulationOptions flightOptions(double duration_s, sim::SceneType scene,
                                     sim::DynamicLevel dynamic, std::uint64_t seed);

/// A blackout applied to a sequence's frames as they are read: both images black from t0_s to t1_s
/// after its first frame.
struct Blackout {
  double t0_s = 0.0;
  double t1_s = 0.0;
  bool covers(double t_s) const { return t_s >= t0_s && t_s < t1_s; }
  /// Blackens both images of `frame`, `t_s` after the first frame, when the blackout covers it.
  void apply(sensors::FrameBundle& frame, double t_s) const;
};

}  // namespace superdyna::test
