// The moving-object test inside the whole pipeline, on a simulated street among moving agents.

#include <gtest/gtest.h>

#include <filesystem>
#include <iostream>
#include <set>

#include "superdyna/eval/dynamic_decisions.h"
#include "superdyna/io/dataset_source.h"
#include "superdyna/system/system.h"
#include "support/generated_sequence.h"

namespace superdyna::system {
namespace {

namespace fs = std::filesystem;

/// A 3 s street flight at the high dynamic level, with instance masks.
const fs::path& highDynamicSequence() {
  sim::SimulationOptions options =
      test::flightOptions(3.0, sim::SceneType::kStreet, sim::DynamicLevel::kHigh, 2);
  options.landmark_count = 0;
  return test::generatedSequence("moving_objects_test_high", options);
}

/// Ids of the agents that move at the sequence's last frame (instance_states.csv).
std::set<int> agentsMovingAtTheEnd(const fs::path& sequence) {
  const eval::InstanceStates states =
      eval::readInstanceStates(sequence / "mav0" / "instance_states.csv");
  const TimeNs last = states.rbegin()->first.first;
  std::set<int> ids;
  for (const auto& [key, moving] : states) {
    if (key.first == last && moving) ids.insert(key.second);
  }
  return ids;
}

struct DynamicRun {
  std::vector<eval::DecisionRow> rows;
  std::size_t points_on_movers = 0;  ///< Final map points on agents moving at the end.
  std::size_t lost = 0;
};

DynamicRun runWith(dynamic::DynamicMode mode) {
  const fs::path& path = highDynamicSequence();
  io::DatasetSourceOptions source_options;
  source_options.instance_masks = true;
  const auto source = io::openDataset(io::DatasetKind::kEuroc, path, source_options);
  SystemOptions options;
  options.mode = SensorMode::kStereoInertial;
  options.tracker.dynamic.mode = mode;
  System slam(options, source->camera0(), source->camera1(), source->imu());
  DynamicRun run;
  slam.run(*source, [&](const tracking::TrackingResult& result) {
    for (const dynamic::ObjectDecision& object : result.moving.objects) {
      run.rows.push_back({result.t_ns, object.instance_id, "", object.pairs, object.tested,
                          dynamic::toString(object.decision), object.keypoints,
                          object.dropped ? object.keypoints : 0});
    }
  });
  const std::set<int> movers = agentsMovingAtTheEnd(path);
  for (const auto& [instance, count] : slam.mapPointsPerInstance()) {
    if (movers.count(instance)) run.points_on_movers += count;
  }
  run.lost = slam.lostFrames();
  return run;
}

TEST(MovingObjects, SemanticGeometricDropsMoversAndKeepsParkedCars) {
  const DynamicRun off = runWith(dynamic::DynamicMode::kOff);
  const DynamicRun tested = runWith(dynamic::DynamicMode::kSemanticGeometric);
  const eval::DecisionScore score = eval::scoreDecisions(
      tested.rows, eval::readInstanceStates(highDynamicSequence() / "mav0" / "instance_states.csv"),
      8);
  const eval::DecisionCounts& c = score.all;
  std::cout << "3 s high-dynamic street, stereo-inertial: " << c.true_moving << " moving / "
            << c.true_static << " static object-frames right, " << c.false_moving
            << " false moving, " << c.missed_moving << " missed; precision " << c.precision()
            << ", recall " << c.recall() << ", static features kept " << c.staticKeptShare()
            << ", moving features dropped " << c.movingDroppedShare()
            << "; final map points on moving agents: off " << off.points_on_movers
            << ", semantic-geometric " << tested.points_on_movers << "\n";
  EXPECT_TRUE(off.rows.empty());
  EXPECT_GT(c.true_moving, 50);
  EXPECT_GE(c.precision(), 0.9);
  EXPECT_GE(c.recall(), 0.9);
  EXPECT_GE(c.staticKeptShare(), 0.85);
  EXPECT_GE(c.movingDroppedShare(), 0.8);
  EXPECT_EQ(c.unknown, 0);
  // Without the test the map keeps points on the movers; with it, far fewer (those left are out
  // of the local map, or were made while the agent stood still).
  EXPECT_GT(off.points_on_movers, 100u);
  EXPECT_LE(tested.points_on_movers * 3, off.points_on_movers);
  EXPECT_EQ(tested.lost, 0u);
}

}  // namespace
}  // namespace superdyna::system
