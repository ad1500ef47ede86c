#include "superdyna/mapping/keyframe_preintegration.h"

namespace superdyna::mapping {

std::optional<imu::Preintegration> preintegrateFromPrevious(const map::KeyFrame& keyframe,
                                                            TimeNs t_previous_ns,
                                                            const imu::Bias& bias,
                                                            const imu::ImuNoise& noise) {
  const auto& samples = keyframe.imu_from_previous;
  if (samples.size() < 2 || !(keyframe.t_ns > t_previous_ns)) return std::nullopt;
  if (samples.front().t_ns > t_previous_ns || samples.back().t_ns < keyframe.t_ns) {
    return std::nullopt;
  }
  imu::Preintegration preintegration(bias, noise);
  preintegration.integrateBetween(samples, t_previous_ns, keyframe.t_ns);
  return preintegration;
}

KeyFramePreintegrations::KeyFramePreintegrations(const imu::ImuNoise& noise,
                                                 const imu::ReintegrationOptions& reintegration)
    : noise_(noise), reintegration_(reintegration) {
  noise_.validate();
  reintegration_.validate();
}

const imu::Preintegration* KeyFramePreintegrations::fromPrevious(const map::Map& map,
                                                                 map::KeyFrameId id) {
  std::optional<imu::Bias> bias_i;
  TimeNs t_previous_ns = 0;
  map::KeyFrameId previous = map::kNoKeyFrame;
  map.readKeyFrame(id, [&](const map::KeyFrame& kf) { previous = kf.previous; });
  if (previous == map::kNoKeyFrame || !map.readKeyFrame(previous, [&](const map::KeyFrame& kf) {
        bias_i = imu::Bias{kf.bg, kf.ba};
        t_previous_ns = kf.t_ns;
      })) {
    cache_.erase(id);
    return nullptr;
  }
  // A cached entry of the same link stays while the predecessor's bias is close to its
  // linearisation bias (first-order corrections); beyond, it is integrated again from the samples
  // at the new bias, as re-integrating its steps would (the cache keeps no steps: they would
  // double the IMU samples' memory over the whole map).
  const auto cached = cache_.find(id);
  if (cached != cache_.end() && cached->second.previous == previous &&
      !cached->second.preintegration.biasMovedBeyond(*bias_i, reintegration_)) {
    return &cached->second.preintegration;
  }
  std::optional<imu::Preintegration> fresh;
  map.readKeyFrame(id, [&](const map::KeyFrame& kf) {
    fresh = preintegrateFromPrevious(kf, t_previous_ns, *bias_i, noise_);
  });
  if (!fresh) {
    cache_.erase(id);
    return nullptr;
  }
  fresh->releaseSteps();
  cache_.insert_or_assign(id, Entry{previous, std::move(*fresh)});
  return &cache_.at(id).preintegration;
}

void KeyFramePreintegrations::prune(const map::Map& map) {
  std::erase_if(cache_, [&](const auto& entry) { return !map.hasKeyFrame(entry.first); });
}

}  // namespace superdyna::mapping
