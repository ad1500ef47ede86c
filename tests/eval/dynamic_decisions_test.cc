#include "superdyna/eval/dynamic_decisions.h"

#include <gtest/gtest.h>

#include <fstream>

#include "superdyna/core/error.h"
#include "support/test_support.h"

namespace superdyna::eval {
namespace {

void writeFile(const std::filesystem::path& path, const std::string& text) {
  std::ofstream(path) << text;
}

constexpr const char* kHeader =
    "t_ns,instance_id,class,pairs,tested,max_distance_px,threshold_px,decision,keypoints,dropped\n";

TEST(DynamicDecisionsTest, ScoresObjectFramesAgainstTheInstanceStates) {
  test::ScratchDir dir("dynamic_decisions_score");
  writeFile(dir.path() / "states.csv",
            "# t_ns,id,moving,pixels_cam0,pixels_cam1\n"
            "100,1,0,500,500\n100,2,1,800,790\n100,3,1,50,40\n"
            "200,1,0,500,500\n200,2,1,800,790\n200,3,0,50,40\n");
  writeFile(dir.path() / "log.csv", std::string(kHeader) +
                                        "100,1,vehicle,20,10,1.0,2.0,static,30,0\n"
                                        "100,2,vehicle,15,10,9.0,2.0,moving,25,25\n"
                                        "100,3,pedestrian,2,2,0.5,2.0,static,4,0\n"
                                        "200,1,vehicle,20,10,3.0,2.0,moving,30,30\n"
                                        "200,2,vehicle,12,10,1.5,2.0,static,20,0\n"
                                        "200,3,pedestrian,9,9,0.1,2.0,unverified,5,5\n"
                                        "300,1,vehicle,20,10,1.0,2.0,static,30,0\n");
  const DecisionScore score = scoreDecisions(readDynamicLog(dir.path() / "log.csv"),
                                             readInstanceStates(dir.path() / "states.csv"), 8);
  const DecisionCounts& all = score.all;
  EXPECT_EQ(all.true_moving, 1);    // 100/2
  EXPECT_EQ(all.false_moving, 1);   // 200/1
  EXPECT_EQ(all.missed_moving, 1);  // 200/2
  EXPECT_EQ(all.true_static, 1);    // 100/1
  EXPECT_EQ(all.unverified, 1);     // 200/3
  EXPECT_EQ(all.few_pairs, 1);      // 100/3
  EXPECT_EQ(all.unknown, 1);        // 300/1
  EXPECT_DOUBLE_EQ(all.precision(), 0.5);
  EXPECT_DOUBLE_EQ(all.recall(), 0.5);
  // Static object-frames: 100/1 (30 kept), 200/1 (0 of 30), 200/3 (0 of 5).
  EXPECT_EQ(all.static_keypoints, 65);
  EXPECT_EQ(all.static_kept, 30);
  // Moving: 100/2 (25 of 25 dropped), 100/3 (0 of 4), 200/2 (0 of 20).
  EXPECT_DOUBLE_EQ(all.movingDroppedShare(), 25.0 / 49.0);
  EXPECT_EQ(score.by_class.at("pedestrian").unverified, 1);
}

TEST(DynamicDecisionsTest, InjectedFalseObjectsAreScoredAsStaticObjects) {
  test::ScratchDir dir("dynamic_decisions_injected");
  writeFile(dir.path() / "states.csv", "100,1,0,500,500\n100,2,1,800,790\n");
  // 32768 and 32769 are injected false objects (semantics.error_*), absent from the truth; 99 is
  // a real id the truth does not list.
  writeFile(dir.path() / "log.csv", std::string(kHeader) +
                                        "100,1,vehicle,20,10,1.0,2.0,static,30,0\n"
                                        "100,2,vehicle,15,10,9.0,2.0,moving,25,25\n"
                                        "100,32768,vehicle,20,10,1.0,2.0,static,40,0\n"
                                        "100,32769,pedestrian,12,10,8.0,2.0,moving,10,10\n"
                                        "100,32770,vehicle,3,3,0.5,2.0,unverified,6,6\n"
                                        "100,99,vehicle,20,10,1.0,2.0,static,30,0\n");
  const DecisionScore score = scoreDecisions(readDynamicLog(dir.path() / "log.csv"),
                                             readInstanceStates(dir.path() / "states.csv"), 8);
  const DecisionCounts& all = score.all;
  EXPECT_EQ(all.true_moving, 1);   // 2
  EXPECT_EQ(all.false_moving, 1);  // 32769: a false object decided moving
  EXPECT_EQ(all.true_static, 2);   // 1, 32768
  EXPECT_EQ(all.few_pairs, 1);     // 32770
  EXPECT_EQ(all.unknown, 1);       // 99
  EXPECT_DOUBLE_EQ(all.precision(), 0.5);
  EXPECT_DOUBLE_EQ(all.recall(), 1.0);
  // Static features: 30 of 30 (id 1), 40 of 40, 0 of 10, 0 of 6.
  EXPECT_EQ(all.static_keypoints, 86);
  EXPECT_EQ(all.static_kept, 70);
  EXPECT_EQ(score.injected.static_keypoints, 56);
  EXPECT_EQ(score.injected.static_kept, 40);
  EXPECT_EQ(score.injected.false_moving, 1);
  EXPECT_EQ(score.injected.unknown, 0);
  EXPECT_EQ(score.by_class.at("pedestrian").false_moving, 1);
  EXPECT_TRUE(isInjectedObject(32768));
  EXPECT_TRUE(isInjectedObject(65534));
  EXPECT_FALSE(isInjectedObject(32767));
  EXPECT_FALSE(isInjectedObject(65535));
}

TEST(DynamicDecisionsTest, MalformedRowNamesFileLineAndField) {
  test::ScratchDir dir("dynamic_decisions_malformed");
  writeFile(dir.path() / "log.csv",
            std::string(kHeader) + "100,1,vehicle,20,10,1.0,2.0,parked,30,0\n");
  try {
    readDynamicLog(dir.path() / "log.csv");
    FAIL() << "no error";
  } catch (const InputError& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("log.csv"), std::string::npos) << what;
    EXPECT_NE(what.find(":2"), std::string::npos) << what;
    EXPECT_NE(what.find("decision"), std::string::npos) << what;
  }
}

}  // namespace
}  // namespace superdyna::eval
