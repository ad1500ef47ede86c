#include <fmt/format.h>
#include <gtest/gtest.h>

#include <cstring>
#include <map>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <set>

#include "superdyna/core/error.h"
#include "superdyna/io/euroc_dataset.h"
#include "superdyna/io/text_table.h"
#include "superdyna/sim/agents.h"
#include "superdyna/sim/hash.h"
#include "superdyna/sim/sequence_generator.h"
#include "superdyna/sim/world_builder.h"
#include "support/test_support.h"

namespace superdyna::sim {
namespace {

/// A camera moving along +x at 1.5 m/s and turning slowly left, 1.5 m above z = 0, looking
/// along its direction of travel.
CameraPath curvedWalk() {
  CameraPath path;
  path.T_w_c = [](TimeNs t) {
    const double s = nsToSeconds(t);
    const double yaw = 0.02 * s;
    Eigen::Matrix3d R_w_fwd = Eigen::AngleAxisd(yaw, Eigen::Vector3d::UnitZ()).toRotationMatrix();
    Eigen::Matrix3d R;
    R.col(0) = -R_w_fwd.col(1);            // image right
    R.col(1) = -Eigen::Vector3d::UnitZ();  // image down
    R.col(2) = R_w_fwd.col(0);             // optical axis
    return SE3d(R, Eigen::Vector3d(1.5 * s, 0.5 * s * yaw, 1.5));
  };
  path.range = {0, 20 * kNsPerSecond};
  path.horizontal_fov_rad = 1.4;
  return path;
}

WorldOptions coarseWorld(SceneType scene, DynamicLevel level, std::uint64_t seed) {
  WorldOptions options;
  options.scene = scene;
  options.dynamic = level;
  options.seed = seed;
  options.texel_scale = 4.0;  // coarse textures: quicker, and the hash covers them all the same
  return options;
}

/// Folds values into a running hash.
class Fingerprint {
 public:
  void add(double value) {
    std::uint64_t bits = 0;
    std::memcpy(&bits, &value, sizeof bits);
    add(bits);
  }
  void add(std::uint64_t value) { hash_ = mix64(hash_ ^ value); }
  void add(const Eigen::Vector3d& v) {
    for (int i = 0; i < 3; ++i)
      add(v[i]);
  }
  void add(const cv::Mat& image) {
    for (int r = 0; r < image.rows; ++r) {
      const auto* row = image.ptr<std::uint8_t>(r);
      const std::size_t bytes = image.cols * image.elemSize();
      for (std::size_t i = 0; i < bytes; i += 8) {
        std::uint64_t word = 0;
        std::memcpy(&word, row + i, std::min<std::size_t>(8, bytes - i));
        add(word);
      }
    }
  }
  std::uint64_t value() const { return hash_; }

 private:
  std::uint64_t hash_ = 0;
};

/// Hash of everything a world holds: textures, every quad, every agent's pose and moving state
/// every 0.1 s, and the agent table.
std::uint64_t worldFingerprint(const World& world, const TimeRange& range) {
  Fingerprint f;
  f.add(world.ground_z);
  for (const Texture& texture : world.scene.textures) {
    f.add(texture.texelSizeM());
    f.add(texture.image());
  }
  for (const SceneObject& object : world.scene.objects) {
    f.add(std::uint64_t{object.instance_id});
    f.add(static_cast<std::uint64_t>(object.object_class));
    for (const Quad& quad : object.quads) {
      f.add(quad.origin);
      f.add(quad.edge_u);
      f.add(quad.edge_v);
      f.add(static_cast<std::uint64_t>(quad.texture));
      f.add(quad.texture_offset_m.x());
      f.add(quad.texture_offset_m.y());
    }
    if (!object.T_w_o) continue;
    for (TimeNs t = range.begin; t <= range.end; t += 100 * kNsPerMillisecond) {
      const auto pose = object.T_w_o(t);
      f.add(std::uint64_t{pose.has_value()});
      if (!pose) continue;
      f.add(pose->t);
      f.add(pose->q.coeffs().head<3>().eval());
      f.add(std::uint64_t{object.is_moving(t)});
    }
  }
  for (const AgentRecord& agent : world.agents) {
    f.add(std::uint64_t{agent.instance_id});
    f.add(static_cast<std::uint64_t>(agent.object_class));
    f.add(std::uint64_t{agent.ever_moving});
    f.add(static_cast<std::uint64_t>(agent.t_begin_ns));
    f.add(static_cast<std::uint64_t>(agent.t_end_ns));
  }
  return f.value();
}

struct LevelFingerprint {
  const char* scene;
  const char* level;
  std::uint64_t hash;
};

// Fingerprints of the worlds of every scene and level for seed 77, computed before the mover
// patterns and unlabelled agents existed (main at 509ed21): the dynamic levels must keep building
// exactly these worlds. They depend on libstdc++'s random distributions, not on the compiler:
// a clang build (build-fuzz) gives the same worlds since no two draws share one expression.
constexpr LevelFingerprint kLevelFingerprints[] = {
    {"street", "none", 0xe8bfcf0c31f4b8edULL},  {"street", "low", 0x7c9292c90c554522ULL},
    {"street", "mid", 0x977271a5d9a562f9ULL},   {"street", "high", 0x500a3475720f62a0ULL},
    {"parking", "none", 0x5781093102477ab3ULL}, {"parking", "low", 0x544ead62bfd8a677ULL},
    {"parking", "mid", 0x5450197f9aa75e73ULL},  {"parking", "high", 0x16ea1402acd13a85ULL},
    {"indoor", "none", 0x1f7b4d1ed379235fULL},  {"indoor", "low", 0xc241cca55f522bbbULL},
    {"indoor", "mid", 0xdc565e58175cdf5cULL},   {"indoor", "high", 0xf549f645019ec8d5ULL},
};

TEST(MoverPatternsTest, DynamicLevelsBuildTheSameWorldsAsBeforeMoverPatterns) {
  const CameraPath path = curvedWalk();
  for (const LevelFingerprint& expected : kLevelFingerprints) {
    const WorldOptions options =
        coarseWorld(parseSceneType(expected.scene), parseDynamicLevel(expected.level), 77);
    const World world = buildWorld(options, path);
    EXPECT_EQ(worldFingerprint(world, path.range), expected.hash)
        << expected.scene << " " << expected.level;
  }
}

WorldOptions patternWorld(MoverPattern pattern, std::uint64_t seed) {
  WorldOptions options = coarseWorld(SceneType::kStreet, DynamicLevel::kLow, seed);
  options.pattern.pattern = pattern;
  return options;
}

TEST(MoverPatternsTest, PatternsAndUnlabelledAgentsAreDeterministicForASeed) {
  const CameraPath path = curvedWalk();
  for (const MoverPattern pattern :
       {MoverPattern::kBus, MoverPattern::kConvoy, MoverPattern::kCrowd}) {
    WorldOptions options = patternWorld(pattern, 77);
    options.unlabelled_share = 0.5;
    options.pattern.slow = pattern == MoverPattern::kCrowd;
    const std::uint64_t first = worldFingerprint(buildWorld(options, path), path.range);
    EXPECT_EQ(worldFingerprint(buildWorld(options, path), path.range), first) << toString(pattern);
    options.seed = 78;
    EXPECT_NE(worldFingerprint(buildWorld(options, path), path.range), first) << toString(pattern);
  }
}

/// The agents a pattern adds to the level's: those after the level's own.
std::vector<const SceneObject*> patternObjects(const World& with, const World& without) {
  std::vector<const SceneObject*> added;
  for (std::size_t i = without.scene.objects.size(); i < with.scene.objects.size(); ++i)
    added.push_back(&with.scene.objects[i]);
  return added;
}

TEST(MoverPatternsTest, PatternsAddCoherentGroupsOfTheirBodiesAndKeepTheLevelsAgents) {
  const CameraPath path = curvedWalk();
  const World level = buildWorld(coarseWorld(SceneType::kStreet, DynamicLevel::kLow, 77), path);
  struct Expected {
    MoverPattern pattern;
    ObjectClass object_class;
    AgentSize size;
    int group_size;
  };
  for (const Expected& expected :
       {Expected{MoverPattern::kBus, ObjectClass::kVehicle, busSize(), 1},
        Expected{MoverPattern::kConvoy, ObjectClass::kVehicle, vehicleSize(), 4},
        Expected{MoverPattern::kCrowd, ObjectClass::kPedestrian, pedestrianSize(), 10}}) {
    SCOPED_TRACE(toString(expected.pattern));
    const World world = buildWorld(patternWorld(expected.pattern, 77), path);
    // The level's agents come first, untouched.
    ASSERT_GT(world.agents.size(), level.agents.size());
    for (std::size_t i = 0; i < level.agents.size(); ++i) {
      EXPECT_EQ(world.agents[i].t_begin_ns, level.agents[i].t_begin_ns);
      EXPECT_EQ(world.agents[i].object_class, level.agents[i].object_class);
    }
    const auto added = patternObjects(world, level);
    ASSERT_EQ(added.size() % expected.group_size, 0u);
    // 20 s of groups one after the other, each a few seconds long.
    EXPECT_GE(added.size() / expected.group_size, 2u);
    std::map<TimeNs, std::vector<const SceneObject*>> groups;  // by start time
    for (std::size_t i = level.agents.size(); i < world.agents.size(); ++i) {
      const AgentRecord& agent = world.agents[i];
      EXPECT_EQ(agent.object_class, expected.object_class);
      EXPECT_TRUE(agent.ever_moving);
      groups[agent.t_begin_ns].push_back(&world.scene.objects[i + 1]);
    }
    for (const auto& [t_begin, members] : groups) {
      ASSERT_EQ(members.size(), static_cast<std::size_t>(expected.group_size));
      // Coherent motion: every member moves by the same displacement over the same second.
      const TimeNs t0 = t_begin + kNsPerSecond / 2, t1 = t0 + kNsPerSecond;
      const auto p0 = members.front()->T_w_o(t0), p1 = members.front()->T_w_o(t1);
      if (!p1) continue;  // a group cut short by the end of the sequence
      ASSERT_TRUE(p0);
      const Eigen::Vector3d step = p1->t - p0->t;
      for (const SceneObject* member : members) {
        const auto a = member->T_w_o(t0), b = member->T_w_o(t1);
        ASSERT_TRUE(a && b);
        EXPECT_LT((b->t - a->t - step).norm(), 1e-9);
        EXPECT_NEAR(member->quads.front().edge_u.norm(), expected.size.length, 1e-12);
        EXPECT_NEAR(-member->quads.front().edge_v.z(), expected.size.height, 1e-12);
      }
    }
  }
}

TEST(MoverPatternsTest, GroupsComeCloseButKeepTheirBodiesClearOfTheCamera) {
  const CameraPath path = curvedWalk();
  for (const MoverPattern pattern :
       {MoverPattern::kBus, MoverPattern::kConvoy, MoverPattern::kCrowd}) {
    const World level = buildWorld(coarseWorld(SceneType::kStreet, DynamicLevel::kLow, 77), path);
    const World world = buildWorld(patternWorld(pattern, 77), path);
    double closest = std::numeric_limits<double>::infinity();
    for (const SceneObject* object : patternObjects(world, level)) {
      const Eigen::Vector3d corner = object->quads.front().origin;  // (-l/2, -w/2, h)
      const Eigen::Vector2d half(-corner.x(), -corner.y());
      for (TimeNs t = path.range.begin; t <= path.range.end; t += 50 * kNsPerMillisecond) {
        const auto pose = object->T_w_o(t);
        if (!pose) continue;
        const Eigen::Vector3d local = pose->inverse() * path.T_w_c(t).t;
        const double gap = (local.head<2>().cwiseAbs() - half).cwiseMax(0.0).norm();
        closest = std::min(closest, gap);
      }
    }
    // Pedestrians keep 0.8 m from the camera, vehicles 1.5 m; the closest is a few metres.
    EXPECT_GT(closest, pattern == MoverPattern::kCrowd ? 0.75 : 1.45) << toString(pattern);
    EXPECT_LT(closest, 5.0) << toString(pattern);
  }
}

TEST(MoverPatternsTest, SlowMoversMoveAtWalkingPace) {
  const CameraPath path = curvedWalk();
  for (const MoverPattern pattern : {MoverPattern::kBus, MoverPattern::kCrowd}) {
    WorldOptions options = patternWorld(pattern, 77);
    const World level = buildWorld(coarseWorld(SceneType::kStreet, DynamicLevel::kLow, 77), path);
    for (const bool slow : {false, true}) {
      options.pattern.slow = slow;
      const World world = buildWorld(options, path);
      for (const SceneObject* object : patternObjects(world, level)) {
        const AgentRecord& agent = world.agents[object->instance_id - 1];
        const TimeNs t0 = agent.t_begin_ns, t1 = t0 + kNsPerSecond / 2;
        const auto p0 = object->T_w_o(t0), p1 = object->T_w_o(t1);
        if (!p1) continue;  // cut short by the end of the sequence
        ASSERT_TRUE(p0);
        const double speed = (p1->t - p0->t).norm() / 0.5;
        const bool people = pattern == MoverPattern::kCrowd;
        const double lo = slow ? (people ? 0.3 : 0.5) : (people ? 1.0 : 2.0);
        const double hi = slow ? (people ? 0.6 : 1.5) : (people ? 1.6 : 5.0);
        EXPECT_GE(speed, lo - 1e-9) << toString(pattern) << " slow " << slow;
        EXPECT_LE(speed, hi + 1e-9) << toString(pattern) << " slow " << slow;
      }
    }
  }
}

TEST(MoverPatternsTest, UnlabelledShareRelabelsMovingAgentsOnlyAndChangesNothingElse) {
  const CameraPath path = curvedWalk();
  WorldOptions options = patternWorld(MoverPattern::kConvoy, 77);
  const World labelled = buildWorld(options, path);
  options.unlabelled_share = 0.5;
  const World half = buildWorld(options, path);
  options.unlabelled_share = 1.0;
  const World all = buildWorld(options, path);
  ASSERT_EQ(half.agents.size(), labelled.agents.size());
  int moving = 0, unlabelled_half = 0;
  for (std::size_t i = 0; i < labelled.agents.size(); ++i) {
    const bool relabelled = half.agents[i].object_class == ObjectClass::kUnlabelled;
    EXPECT_EQ(half.scene.objects[i + 1].object_class, half.agents[i].object_class);
    if (!labelled.agents[i].ever_moving) {
      EXPECT_EQ(half.agents[i].object_class, labelled.agents[i].object_class);
      EXPECT_EQ(all.agents[i].object_class, labelled.agents[i].object_class);
      continue;
    }
    ++moving;
    unlabelled_half += relabelled ? 1 : 0;
    EXPECT_EQ(all.agents[i].object_class, ObjectClass::kUnlabelled);
    if (!relabelled) {
      EXPECT_EQ(half.agents[i].object_class, labelled.agents[i].object_class);
    }
  }
  EXPECT_GT(moving, 10);
  EXPECT_GT(unlabelled_half, 0.25 * moving);
  EXPECT_LT(unlabelled_half, 0.75 * moving);
  // Apart from the classes, the same world: every texture, quad and pose.
  World restored = buildWorld(options, path);
  for (std::size_t i = 0; i < restored.agents.size(); ++i) {
    restored.agents[i].object_class = labelled.agents[i].object_class;
    restored.scene.objects[i + 1].object_class = labelled.scene.objects[i + 1].object_class;
  }
  EXPECT_EQ(worldFingerprint(restored, path.range), worldFingerprint(labelled, path.range));
}

TEST(MoverPatternsTest, BadPatternOptionsGiveClearErrors) {
  EXPECT_EQ(parseMoverPattern("convoy"), MoverPattern::kConvoy);
  EXPECT_EQ(toString(MoverPattern::kCrowd), "crowd");
  test::expectError<OptionError>(
      [] { parseMoverPattern("tram"); },
      {"dynamic-pattern", "unknown mover pattern 'tram'", "none|bus|convoy|crowd"});
  WorldOptions options = patternWorld(MoverPattern::kBus, 1);
  options.pattern.group_size = 51;
  test::expectError<OptionError>([&] { options.validate(); }, {"pattern-size", "[0, 50]"});
  options.pattern.group_size = 2;
  options.pattern.min_distance_m = 6.0;
  options.pattern.max_distance_m = 3.0;
  test::expectError<OptionError>([&] { options.validate(); },
                                 {"pattern-distance", "MIN <= MAX", "6,3"});
  options.pattern.min_distance_m = 0.5;
  test::expectError<OptionError>([&] { options.validate(); }, {"pattern-distance", "1 <= MIN"});
  options.pattern.min_distance_m = 3.0;
  options.pattern.max_distance_m = 6.0;
  options.validate();
  options.unlabelled_share = 1.5;
  test::expectError<OptionError>([&] { options.validate(); }, {"unlabelled", "[0, 1]", "1.5"});
  options.unlabelled_share = 0.0;
  options.scene = SceneType::kIndoor;
  test::expectError<OptionError>([&] { options.validate(); },
                                 {"dynamic-pattern", "'bus'", "street or parking"});
  options.pattern.pattern = MoverPattern::kCrowd;
  options.validate();
  options.pattern.pattern = MoverPattern::kNone;
  test::expectError<OptionError>([&] { options.validate(); },
                                 {"pattern-size", "needs --dynamic-pattern"});
  options.pattern = {};
  options.pattern.slow = true;
  test::expectError<OptionError>([&] { options.validate(); },
                                 {"slow-movers", "needs --dynamic-pattern"});
}

// ---------------------------------------------------------------- written sequences

/// A small rendered street sequence (188x120 px, 1.5 s, coarse textures) with a crowd passing.
SimulationOptions smallCrowdSequence(const std::filesystem::path& out, double unlabelled_share) {
  SimulationOptions options;
  options.output_dir = out;
  options.motion.duration_s = 1.5;
  options.world.scene = SceneType::kStreet;
  options.world.dynamic = DynamicLevel::kMid;
  options.world.texel_scale = 4.0;
  options.world.pattern.pattern = MoverPattern::kCrowd;
  options.world.unlabelled_share = unlabelled_share;
  options.rig.width = 188;
  options.rig.height = 120;
  options.rig.fx = options.rig.fy = 0.25 * 458.0;
  options.rig.cx = 94.0;
  options.rig.cy = 60.0;
  options.noise = false;
  options.landmark_count = 0;
  options.seed = 11;
  return options;
}

/// One row of instance_states.csv.
struct StateRow {
  TimeNs t_ns;
  int id;
  bool moving;
  int pixels_cam0;
  std::string object_class;
};

std::vector<StateRow> readStates(const std::filesystem::path& mav0) {
  std::vector<StateRow> rows;
  for (const auto& row : io::readTextRows(mav0 / "instance_states.csv", io::Delimiter::kComma)) {
    rows.push_back({std::stoll(row.fields[0]), std::stoi(row.fields[1]), row.fields[2] == "1",
                    std::stoi(row.fields[3]), row.fields[5]});
  }
  return rows;
}

cv::Mat readMask(const std::filesystem::path& mav0, int cam, TimeNs t) {
  return cv::imread((mav0 / fmt::format("cam{}/mask/{}.png", cam, t)).string(),
                    cv::IMREAD_UNCHANGED);
}

class MoverSequenceTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new test::ScratchDir("mover_sequence");
    labelled_summary_ = generateSequence(smallCrowdSequence(dir_->path() / "labelled", 0.0));
    unlabelled_summary_ = generateSequence(smallCrowdSequence(dir_->path() / "unlabelled", 0.5));
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }
  static std::filesystem::path mav0(const char* name) { return dir_->path() / name / "mav0"; }

  static test::ScratchDir* dir_;
  static SimulationSummary labelled_summary_, unlabelled_summary_;
};

test::ScratchDir* MoverSequenceTest::dir_ = nullptr;
SimulationSummary MoverSequenceTest::labelled_summary_;
SimulationSummary MoverSequenceTest::unlabelled_summary_;

TEST_F(MoverSequenceTest, UnlabelledAgentsAreInTheInstanceTablesButNotInTheMasks) {
  std::set<int> unlabelled;
  for (const auto& row :
       io::readTextRows(mav0("unlabelled") / "instances.csv", io::Delimiter::kComma)) {
    if (row.fields[1] == "unlabelled") unlabelled.insert(std::stoi(row.fields[0]));
  }
  ASSERT_GT(unlabelled.size(), 3u);
  int unlabelled_rows = 0, unlabelled_pixels = 0;
  for (const StateRow& row : readStates(mav0("unlabelled"))) {
    EXPECT_EQ(row.object_class == "unlabelled", unlabelled.contains(row.id)) << row.id;
    const cv::Mat mask = readMask(mav0("unlabelled"), 0, row.t_ns);
    const cv::Mat full = readMask(mav0("labelled"), 0, row.t_ns);
    ASSERT_EQ(mask.type(), CV_16UC1);
    // The table keeps the rendered pixel count; the mask holds the agent only when labelled.
    EXPECT_EQ(cv::countNonZero(full == row.id), row.pixels_cam0) << row.id;
    if (unlabelled.contains(row.id)) {
      EXPECT_EQ(cv::countNonZero(mask == row.id), 0) << row.id;
      ++unlabelled_rows;
      unlabelled_pixels += row.pixels_cam0;
    } else {
      EXPECT_EQ(cv::countNonZero(mask == row.id), row.pixels_cam0) << row.id;
    }
  }
  EXPECT_GT(unlabelled_rows, 20);
  EXPECT_GT(unlabelled_pixels, 1000);
  // Both cameras' masks drop them; the images are those of the labelled sequence.
  const auto frames = io::readTextRows(mav0("unlabelled") / "cam1/data.csv", io::Delimiter::kComma);
  for (const auto& frame : frames) {
    const TimeNs t = std::stoll(frame.fields[0]);
    const cv::Mat mask = readMask(mav0("unlabelled"), 1, t);
    for (const int id : unlabelled)
      EXPECT_EQ(cv::countNonZero(mask == id), 0);
    for (const char* cam : {"cam0", "cam1"}) {
      const std::string image = fmt::format("{}/data/{}", cam, frame.fields[1]);
      EXPECT_EQ(test::readFile(mav0("unlabelled") / image),
                test::readFile(mav0("labelled") / image));
    }
  }
  // The dataset reader accepts the class and serves masks without those agents.
  const io::EurocDataset dataset = io::EurocDataset::open(mav0("unlabelled"));
  ASSERT_TRUE(dataset.hasInstanceMasks());
  for (const int id : unlabelled)
    EXPECT_FALSE(dataset.instanceClasses().contains(id));
  EXPECT_FALSE(dataset.instanceClasses().empty());
  for (const io::StereoFrameRef& frame : dataset.stereoFrames()) {
    EXPECT_NO_THROW(dataset.loadInstanceMask(frame.cam0, cv::Size(188, 120)));
  }
}

TEST_F(MoverSequenceTest, FrameStatsCountTheMovingPixelsAndCornersOfEachFrame) {
  std::map<TimeNs, std::map<int, bool>> moving;  // per frame: id -> moving
  std::map<TimeNs, std::set<int>> unlabelled_moving;
  for (const StateRow& row : readStates(mav0("unlabelled"))) {
    moving[row.t_ns][row.id] = row.moving;
    if (row.moving && row.object_class == "unlabelled") unlabelled_moving[row.t_ns].insert(row.id);
  }
  double share_sum = 0.0, share_max = 0.0, corner_share_sum = 0.0;
  int frames = 0, frames_with_movers = 0;
  for (const auto& row :
       io::readTextRows(mav0("unlabelled") / "frame_stats.csv", io::Delimiter::kComma)) {
    const TimeNs t = std::stoll(row.fields[0]);
    // Count in the labelled sequence's mask (every agent in it) and its image.
    const cv::Mat mask = readMask(mav0("labelled"), 0, t);
    int agent_pixels = 0, moving_pixels = 0, unlabelled_pixels = 0;
    for (int r = 0; r < mask.rows; ++r) {
      for (int c = 0; c < mask.cols; ++c) {
        const int id = mask.at<std::uint16_t>(r, c);
        if (id == 0) continue;
        ++agent_pixels;
        if (!moving[t][id]) continue;
        ++moving_pixels;
        unlabelled_pixels += unlabelled_moving[t].contains(id) ? 1 : 0;
      }
    }
    const cv::Mat image = cv::imread(
        (mav0("unlabelled") / fmt::format("cam0/data/{}.png", t)).string(), cv::IMREAD_GRAYSCALE);
    std::vector<cv::KeyPoint> corners;
    cv::FAST(image, corners, 20, true);
    int moving_corners = 0;
    for (const cv::KeyPoint& corner : corners) {
      const int id =
          mask.at<std::uint16_t>(static_cast<int>(corner.pt.y), static_cast<int>(corner.pt.x));
      moving_corners += id != 0 && moving[t][id] ? 1 : 0;
    }
    EXPECT_EQ(std::stoi(row.fields[1]), agent_pixels) << t;
    EXPECT_EQ(std::stoi(row.fields[2]), moving_pixels) << t;
    EXPECT_EQ(std::stoi(row.fields[3]), unlabelled_pixels) << t;
    EXPECT_EQ(std::stoi(row.fields[5]), static_cast<int>(corners.size())) << t;
    EXPECT_EQ(std::stoi(row.fields[6]), moving_corners) << t;
    const double share = moving_pixels / (188.0 * 120.0);
    share_sum += share;
    share_max = std::max(share_max, share);
    corner_share_sum += corners.empty() ? 0.0 : double(moving_corners) / corners.size();
    frames_with_movers += moving_pixels > 0 ? 1 : 0;
    ++frames;
  }
  ASSERT_EQ(frames, unlabelled_summary_.frames);
  EXPECT_GT(frames_with_movers, frames / 2);
  EXPECT_NEAR(unlabelled_summary_.mean_moving_coverage, share_sum / frames, 1e-12);
  EXPECT_NEAR(unlabelled_summary_.max_moving_coverage, share_max, 1e-12);
  EXPECT_NEAR(unlabelled_summary_.mean_moving_corner_share, corner_share_sum / frames, 1e-12);
  EXPECT_GT(unlabelled_summary_.mean_unlabelled_moving_coverage, 0.0);
  EXPECT_EQ(labelled_summary_.mean_unlabelled_moving_coverage, 0.0);
  // Relabelling changes no pixel: the same moving share.
  EXPECT_EQ(labelled_summary_.mean_moving_coverage, unlabelled_summary_.mean_moving_coverage);
  EXPECT_GT(share_max, 0.05);
  // The settings file records the options.
  const std::string yaml = test::readFile(dir_->path() / "unlabelled" / "simulation.yaml");
  for (const char* line : {"dynamic_pattern: crowd\n", "unlabelled_share: 0.5\n",
                           "slow_movers: false\n", "pattern_size: 0\n"}) {
    EXPECT_NE(yaml.find(line), std::string::npos) << line;
  }
  EXPECT_NE(yaml.find("mean_moving_coverage: "), std::string::npos);
}

}  // namespace
}  // namespace superdyna::sim
