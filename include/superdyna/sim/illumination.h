#pragma once
// Time-varying global brightness of the synthetic cameras: the exposure gain the renderer applies
// to the scene radiance before sensor noise, saturation and quantisation. Three effects, each
// optional, multiply:
//
//   drift:   1 + A_d sin(2 pi (t - t0) / P)          slow change of the lighting (clouds, lamps)
//   steps:   piecewise constant over intervals of S   abrupt auto-exposure / light-switch jumps;
//            interval 0 has gain 1, then levels alternate brighter / darker with
//            |log gain| uniform in [0.5, 1] * log(1 + A_s)
//   flicker: 1 + A_f (2 u - 1), u uniform in [0, 1)  independent per frame and per camera
//
// with a constant base gain (below 1: a dim scene, where the sensor noise weighs more), and cam1
// is further scaled by stereo_gain_ratio (a constant auto-exposure mismatch between the cameras).
// Every value is a pure function of (options, seed, camera, time): deterministic.

#include <cstdint>
#include <string>

#include "superdyna/core/time.h"

namespace superdyna::sim {

struct IlluminationOptions {
  double base_gain = 1.0;  ///< Constant gain of both cameras, in [0.05, 4].
  bool drift = false;
  double drift_amplitude = 0.4;  ///< Relative swing A_d of the sinusoid, [0, 0.9].
  double drift_period_s = 20.0;  ///< Period P [s], > 0.
  bool steps = false;
  double step_amplitude = 0.6;   ///< A_s: levels within [1 / (1 + A_s), 1 + A_s], [0, 4].
  double step_interval_s = 5.0;  ///< S: time between steps [s], > 0.
  bool flicker = false;
  double flicker_amplitude = 0.1;  ///< A_f: per-frame relative jitter, [0, 0.5].
  double stereo_gain_ratio = 1.0;  ///< cam1 gain / cam0 gain, in [0.25, 4].

  /// True when some effect changes a gain away from 1.
  bool active() const {
    return drift || steps || flicker || base_gain != 1.0 || stereo_gain_ratio != 1.0;
  }
  /// Throws OptionError naming the first invalid field (as its command-line option).
  void validate() const;
};

/// Turns effects on from a comma-separated list of none, drift, steps, flicker, all (e.g.
/// "drift,flicker"); effects not listed are turned off. Throws OptionError("illumination") for an
/// unknown name or an empty list.
void setIlluminationModes(const std::string& list, IlluminationOptions* options);
/// The effects that are on, as setIlluminationModes() accepts them ("none" when none is).
std::string illuminationModes(const IlluminationOptions& options);

/// The gain of each camera over time, for a sequence that starts at t0_ns.
class IlluminationSchedule {
 public:
  /// Validates the options.
  IlluminationSchedule(const IlluminationOptions& options, std::uint64_t seed, TimeNs t0_ns);

  /// Gain of camera `camera` (0 or 1) for the frame at t_ns; exactly 1 when no effect is on.
  double gain(int camera, TimeNs t_ns) const;

  double driftFactor(TimeNs t_ns) const;
  double stepFactor(TimeNs t_ns) const;
  double flickerFactor(int camera, TimeNs t_ns) const;

 private:
  IlluminationOptions options_;
  std::uint64_t seed_;
  TimeNs t0_ns_;
};

}  // namespace superdyna::sim
