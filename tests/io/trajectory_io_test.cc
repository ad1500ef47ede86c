#include "superdyna/io/trajectory_io.h"

#include <gtest/gtest.h>

#include "superdyna/core/error.h"
#include "support/test_support.h"

namespace superdyna::io {
namespace {

using test::ScratchDir;
using test::writeFile;

Trajectory makeTrajectory() {
  Trajectory trajectory;
  for (int i = 0; i < 20; ++i) {
    const double s = 0.1 * i;
    trajectory.push_back({1403636580838560000LL + i * 50'000'000LL + i,
                          SE3d(expSO3(Eigen::Vector3d(0.1 * s, -0.2, 0.3 * s)),
                               Eigen::Vector3d(s, std::sin(s), 0.5 * s * s))});
  }
  return trajectory;
}

void expectSame(const Trajectory& a, const Trajectory& b, double tolerance) {
  ASSERT_EQ(a.size(), b.size());
  for (std::size_t i = 0; i < a.size(); ++i) {
    EXPECT_EQ(a[i].t_ns, b[i].t_ns) << "pose " << i;
    EXPECT_LT((a[i].T_w_x.matrix() - b[i].T_w_x.matrix()).norm(), tolerance) << "pose " << i;
  }
}

TEST(TrajectoryIoTest, RoundTripsEveryFormat) {
  ScratchDir dir("traj_roundtrip");
  const Trajectory original = makeTrajectory();
  for (auto format : {TrajectoryFormat::kTum, TrajectoryFormat::kEuroc}) {
    const auto file = dir / ("t_" + toString(format) + ".txt");
    writeTrajectory(file, original, format);
    EXPECT_EQ(detectTrajectoryFormat(file), format);
    expectSame(readTrajectory(file), original, 1e-8);
  }
  const auto kitti = dir / "kitti.txt";
  writeTrajectory(kitti, original, TrajectoryFormat::kKitti);
  EXPECT_EQ(detectTrajectoryFormat(kitti), TrajectoryFormat::kKitti);
  const Trajectory from_kitti = readTrajectory(kitti);
  ASSERT_EQ(from_kitti.size(), original.size());
  EXPECT_EQ(from_kitti[3].t_ns, 300'000'000LL);  // default 10 Hz timestamps
  EXPECT_LT((from_kitti[7].T_w_x.matrix() - original[7].T_w_x.matrix()).norm(), 1e-8);
}

TEST(TrajectoryIoTest, SkipsHeaderLinesBeforeData) {
  ScratchDir dir("traj_header");
  const auto file = dir / "openloris_like.txt";
  writeFile(file,
            "scene: market\nframe: base_link\n\nseq: 1\n"
            "1563003603.73554158 -125.1 -15.1 0 0 0 0.640510 0.767950\n"
            "1563003603.76554158 -125.0 -15.0 0 0 0 0.640510 0.767950\n");
  const Trajectory t = readTrajectory(file);
  ASSERT_EQ(t.size(), 2u);
  EXPECT_EQ(t[0].t_ns, 1563003603735541580LL);
  EXPECT_DOUBLE_EQ(t[1].T_w_x.t.x(), -125.0);
}

TEST(TrajectoryIoTest, RejectsSegmentNumbersThatAreNotWholeNumbers) {
  // Found by fuzzing (fuzz/trajectory_fuzzer.cc): a huge "seq:" number was converted to int
  // (undefined behaviour) instead of being reported.
  ScratchDir dir("traj_segment_number");
  const auto file = dir / "segments.txt";
  const std::string row = "1563003603.73554158 -125.1 -15.1 0 0 0 0.640510 0.767950\n";
  for (const std::string number : {"2.66667e+86", "1.5", "-3e9"}) {
    writeFile(file, "scene: market\nseq: " + number + "\n" + row);
    test::expectError([&] { readTrajectory(file); },
                      {"segments.txt:2 [seq]", "not a segment number"});
  }
  writeFile(file, "scene: market\nseq: 2\n" + row);
  TrajectoryReadOptions options;
  options.segment = 2;
  EXPECT_EQ(readTrajectory(file, options).size(), 1u);
}

TEST(TrajectoryIoTest, ReadsTumFilesWithNanosecondTimesAsOrbSlam3WritesThem) {
  ScratchDir dir("trajectory_tum_ns");
  // ORB-SLAM3's SaveTrajectoryEuRoC: TUM columns, the time as a fixed-point nanosecond count.
  writeFile(dir / "f_orbslam3.txt",
            "1403636579763555584.000000 0.1 0.2 0.3 0 0 0 1\n"
            "1403636579813555456.000000 0.2 0.2 0.3 0 0 0 1\n");
  TrajectoryReadOptions options;
  options.format = TrajectoryFormat::kTum;
  options.tum_time_in_ns = true;
  const Trajectory t = readTrajectory(dir / "f_orbslam3.txt", options);
  ASSERT_EQ(t.size(), 2u);
  // Doubles hold these times to 256 ns; the association tolerance is milliseconds.
  EXPECT_NEAR(static_cast<double>(t[0].t_ns), 1403636579763555584.0, 256.0);
  EXPECT_NEAR(static_cast<double>(t[1].t_ns - t[0].t_ns), 50e6, 512.0);
  // Read as seconds, the same file overflows the nanosecond clock: refused, not wrapped.
  EXPECT_THROW(readTrajectory(dir / "f_orbslam3.txt"), InputError);
  options.format = TrajectoryFormat::kEuroc;
  test::expectError<OptionError>([&] { readTrajectory(dir / "f_orbslam3.txt", options); },
                                 {"nanosecond", "TUM"});
  writeFile(dir / "negative.txt", "-5 0 0 0 0 0 0 1\n");
  options.format = TrajectoryFormat::kTum;
  test::expectError([&] { readTrajectory(dir / "negative.txt", options); },
                    {"negative.txt:1", "not a time in nanoseconds"});
}

TEST(TrajectoryIoTest, ReadsOpenLorisSegments) {
  SUPERDYNA_REQUIRE_SHARED(market, "data/trajectories/openloris/market_1.txt");
  const Trajectory all = readTrajectory(market);
  TrajectoryReadOptions options;
  options.segment = 2;
  const Trajectory second = readTrajectory(market, options);
  EXPECT_EQ(second.front().t_ns, 1563004641138520000LL);  // first row after "seq: 2"
  EXPECT_LT(second.size(), all.size());
  options.segment = 9;
  test::expectError([&] { readTrajectory(market, options); }, {"seq: 9", "segments found: 1, 2"});
}

TEST(TrajectoryIoTest, ReadsRealTrajectories) {
  SUPERDYNA_REQUIRE_SHARED(euroc, "data/trajectories/euroc/MH_01_easy.txt");
  const Trajectory mh01 = readTrajectory(euroc);
  EXPECT_GT(mh01.size(), 30000u);
  EXPECT_EQ(mh01.front().t_ns, 1403636580838560000LL);
  EXPECT_DOUBLE_EQ(mh01.front().T_w_x.t.x(), 4.688319);

  SUPERDYNA_REQUIRE_SHARED(market, "data/trajectories/openloris/market_1.txt");
  EXPECT_EQ(detectTrajectoryFormat(market), TrajectoryFormat::kTum);
  EXPECT_GT(readTrajectory(market).size(), 29000u);

  SUPERDYNA_REQUIRE_SHARED(kitti, "data/trajectories/kitti/00.txt");
  SUPERDYNA_REQUIRE_SHARED(times, "data/trajectories/kitti/00_times.txt");
  TrajectoryReadOptions options;
  options.kitti_times = times;
  const Trajectory k00 = readTrajectory(kitti, options);
  EXPECT_EQ(k00.size(), 4541u);
  EXPECT_EQ(k00[1].t_ns, 103'735'900LL);
  EXPECT_NEAR(k00[1].T_w_x.t.z(), 0.8586941, 1e-12);
}

TEST(TrajectoryIoTest, RejectsCorruptRowsNamingFileAndLine) {
  ScratchDir dir("traj_corrupt");
  const std::string good = "1.0 0 0 0 0 0 0 1\n";
  struct Case {
    std::string content;
    std::vector<std::string> fragments;
  };
  const std::vector<Case> cases = {
      {good + "2.0 1 2 3 0 0\n", {"bad.txt:2", "expected 8 fields, found 6"}},
      {good + "2.0 1 nan 3 0 0 0 1\n", {"bad.txt:2", "[ty]", "not finite"}},
      {good + "2.0 1 x 3 0 0 0 1\n", {"bad.txt:2", "[ty]", "not a number"}},
      {good + "1.0 1 2 3 0 0 0 1\n", {"bad.txt:2", "duplicate timestamp"}},
      {good + "0.5 1 2 3 0 0 0 1\n", {"bad.txt:2", "earlier than the previous"}},
      {good + "2.0 1 2 3 0 0 0 2\n", {"bad.txt:2", "quaternion norm"}},
      {good + "2.0 1 2 3 0 0 0 inf\n", {"bad.txt:2", "[qw]", "not finite"}},
  };
  for (const Case& c : cases) {
    const auto file = dir / "bad.txt";
    writeFile(file, c.content);
    std::vector<std::string> fragments = c.fragments;
    test::expectError([&] { readTrajectory(file); }, {fragments[0], fragments[1]});
    if (fragments.size() > 2) test::expectError([&] { readTrajectory(file); }, {fragments[2]});
  }
}

TEST(TrajectoryIoTest, RejectsBadKittiAndMissingFiles) {
  ScratchDir dir("traj_kitti_bad");
  const auto file = dir / "poses.txt";
  writeFile(file, "1 0 0 0 0 1 0 0 0 0 1 0\n2 0 0 0 0 1 0 0 0 0 1 0\n");
  test::expectError([&] { readTrajectory(file); }, {"poses.txt:2", "not orthonormal"});
  test::expectError([&] { readTrajectory(dir / "absent.txt"); }, {"absent.txt", "does not exist"});
  writeFile(file, "1 0 0 0 0 1 0 0 0 0 1 0\n1 0 0 0 0 1 0 0 0 0 1 0\n");
  const auto times = dir / "times.txt";
  writeFile(times, "0.0\n");
  TrajectoryReadOptions options;
  options.kitti_times = times;
  test::expectError([&] { readTrajectory(file, options); }, {"poses.txt:2", "more poses than"});
  writeFile(times, "0.0\n0.0\n");
  test::expectError([&] { readTrajectory(file, options); }, {"times.txt:2", "duplicate"});
}

}  // namespace
}  // namespace superdyna::io
