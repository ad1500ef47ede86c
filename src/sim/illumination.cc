#include "superdyna/sim/illumination.h"

#include <fmt/format.h>
#include <fmt/ranges.h>

#include <cmath>
#include <sstream>
#include <vector>

#include "superdyna/core/error.h"
#include "superdyna/sim/hash.h"

namespace superdyna::sim {

namespace {

/// Salts that keep the step levels and the flicker unrelated to each other and to the image
/// noise, which hashes the same seed.
constexpr std::uint64_t kStepSalt = 0x57e95a17ULL;
constexpr std::uint64_t kFlickerSalt = 0xf11c4e2bULL;

void requireRange(double value, double low, double high, const char* option) {
  if (!(value >= low && value <= high)) {
    throw OptionError(option, fmt::format("must be in [{}, {}], got {}", low, high, value));
  }
}

void requirePositive(double value, const char* option) {
  if (!(value > 0.0) || !std::isfinite(value)) {
    throw OptionError(option, fmt::format("must be > 0, got {}", value));
  }
}

}  // namespace

void IlluminationOptions::validate() const {
  requireRange(base_gain, 0.05, 4.0, "illumination-gain");
  requireRange(drift_amplitude, 0.0, 0.9, "illumination-drift");
  requirePositive(drift_period_s, "illumination-drift-period");
  requireRange(step_amplitude, 0.0, 4.0, "illumination-step");
  requirePositive(step_interval_s, "illumination-step-interval");
  requireRange(flicker_amplitude, 0.0, 0.5, "illumination-flicker");
  requireRange(stereo_gain_ratio, 0.25, 4.0, "stereo-gain-ratio");
}

void setIlluminationModes(const std::string& list, IlluminationOptions* options) {
  IlluminationOptions modes = *options;
  modes.drift = modes.steps = modes.flicker = false;
  std::istringstream in(list);
  std::string name;
  int names = 0;
  while (std::getline(in, name, ',')) {
    ++names;
    if (name == "drift") {
      modes.drift = true;
    } else if (name == "steps") {
      modes.steps = true;
    } else if (name == "flicker") {
      modes.flicker = true;
    } else if (name == "all") {
      modes.drift = modes.steps = modes.flicker = true;
    } else if (name != "none") {
      throw OptionError("illumination",
                        fmt::format("unknown effect '{}' in '{}'; use a comma-separated list of "
                                    "none, drift, steps, flicker, all",
                                    name, list));
    }
  }
  if (names == 0) throw OptionError("illumination", "empty list; use none to turn it off");
  *options = modes;
}

std::string illuminationModes(const IlluminationOptions& options) {
  std::vector<std::string> modes;
  if (options.drift) modes.emplace_back("drift");
  if (options.steps) modes.emplace_back("steps");
  if (options.flicker) modes.emplace_back("flicker");
  return modes.empty() ? std::string("none") : fmt::format("{}", fmt::join(modes, ","));
}

IlluminationSchedule::IlluminationSchedule(const IlluminationOptions& options, std::uint64_t seed,
                                           TimeNs t0_ns)
    : options_(options), seed_(seed), t0_ns_(t0_ns) {
  options_.validate();
}

double IlluminationSchedule::driftFactor(TimeNs t_ns) const {
  if (!options_.drift) return 1.0;
  const double phase = 2.0 * M_PI * nsToSeconds(t_ns - t0_ns_) / options_.drift_period_s;
  return 1.0 + options_.drift_amplitude * std::sin(phase);
}

double IlluminationSchedule::stepFactor(TimeNs t_ns) const {
  if (!options_.steps) return 1.0;
  const auto interval =
      static_cast<std::int64_t>(std::floor(nsToSeconds(t_ns - t0_ns_) / options_.step_interval_s));
  if (interval == 0) return 1.0;  // the sequence starts at the nominal exposure
  const double u =
      unitFromHash(mix64(mix64(seed_ ^ kStepSalt) + static_cast<std::uint64_t>(interval)));
  const double log_gain = (0.5 + 0.5 * u) * std::log1p(options_.step_amplitude);
  return std::exp(interval % 2 != 0 ? log_gain : -log_gain);
}

double IlluminationSchedule::flickerFactor(int camera, TimeNs t_ns) const {
  if (!options_.flicker) return 1.0;
  const std::uint64_t key = mix64(seed_ ^ kFlickerSalt) ^ mix64(static_cast<std::uint64_t>(t_ns));
  const double u = unitFromHash(mix64(key + static_cast<std::uint64_t>(camera)));
  return 1.0 + options_.flicker_amplitude * (2.0 * u - 1.0);
}

double IlluminationSchedule::gain(int camera, TimeNs t_ns) const {
  const double stereo = camera == 1 ? options_.stereo_gain_ratio : 1.0;
  return options_.base_gain * driftFactor(t_ns) * stepFactor(t_ns) * flickerFactor(camera, t_ns) *
         stereo;
}

}  // namespace superdyna::sim
