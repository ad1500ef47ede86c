#include "support/generated_sequence.h"

#include <map>
#include <memory>
#include <mutex>

#include "support/test_support.h"

namespace superdyna::test {

namespace {

struct Generated {
  std::unique_ptr<ScratchDir> dir;
  std::filesystem::path sequence;
};

}  // namespace

const std::filesystem::path& generatedSequence(const std::string& name,
                                               sim::SimulationOptions options) {
  static std::mutex mutex;
  static std::map<std::string, Generated> generated;  // node-based: references stay valid
  const std::lock_guard lock(mutex);
  auto found = generated.find(name);
  if (found == generated.end()) {
    Generated entry{std::make_unique<ScratchDir>(name), {}};
    options.output_dir = entry.dir->path() / "seq";
    options.overwrite = true;
    sim::generateSequence(options);
    entry.sequence = options.output_dir;
    found = generated.emplace(name, std::move(entry)).first;
  }
  return found->second.sequence;
}

sim::SimulationOptions flightOptions(double duration_s, sim::SceneType scene,
                                     sim::DynamicLevel dynamic, std::uint64_t seed) {
  sim::SimulationOptions options;
  options.motion.duration_s = duration_s;
  options.world.scene = scene;
  options.world.dynamic = dynamic;
  options.seed = seed;
  return options;
}

void Blackout::apply(sensors::FrameBundle& frame, double t_s) const {
  if (!covers(t_s)) return;
  frame.image0.setTo(0);
  if (!frame.image1.empty()) frame.image1.setTo(0);
}

}  // namespace superdyna::test
