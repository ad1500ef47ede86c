#include "superdyna/sim/world_builder.h"

#include <gtest/gtest.h>

#include <functional>
#include <opencv2/core.hpp>
#include <set>
#include <utility>

#include "superdyna/core/error.h"
#include "superdyna/sim/agents.h"

namespace superdyna::sim {
namespace {

/// A camera driving along +x at 5 m/s, 1.5 m above z = 0, looking forward (z_c = +x).
CameraPath straightDrive() {
  CameraPath path;
  Eigen::Matrix3d R;
  R.col(0) = -Eigen::Vector3d::UnitY();  // image right
  R.col(1) = -Eigen::Vector3d::UnitZ();  // image down
  R.col(2) = Eigen::Vector3d::UnitX();   // optical axis
  path.T_w_c = [R](TimeNs t) { return SE3d(R, Eigen::Vector3d(5.0 * nsToSeconds(t), 0, 1.5)); };
  path.range = {0, 20 * kNsPerSecond};
  path.horizontal_fov_rad = 1.4;
  return path;
}

WorldOptions coarseWorld(SceneType scene, DynamicLevel level) {
  WorldOptions options;
  options.scene = scene;
  options.dynamic = level;
  options.texel_scale = 4.0;  // coarse textures: the test is about geometry
  return options;
}

int countAgents(const World& world, bool moving) {
  int n = 0;
  for (const auto& agent : world.agents)
    n += agent.ever_moving == moving;
  return n;
}

TEST(WorldBuilderTest, EveryLevelHasStaticAgentsAndMovingOnesGrowWithTheLevel) {
  const CameraPath path = straightDrive();
  int previous_moving = -1;
  for (auto level :
       {DynamicLevel::kNone, DynamicLevel::kLow, DynamicLevel::kMid, DynamicLevel::kHigh}) {
    const World world = buildWorld(coarseWorld(SceneType::kStreet, level), path);
    EXPECT_GT(countAgents(world, false), 5) << toString(level);
    const int moving = countAgents(world, true);
    if (level == DynamicLevel::kNone) {
      EXPECT_EQ(moving, 0);
    }
    EXPECT_GT(moving, previous_moving) << toString(level);
    previous_moving = moving;
    EXPECT_NEAR(world.ground_z, 1.5 - 1.2, 1e-12);
  }
}

TEST(WorldBuilderTest, AgentsKeepClearOfTheCamera) {
  const CameraPath path = straightDrive();
  const World world = buildWorld(coarseWorld(SceneType::kStreet, DynamicLevel::kHigh), path);
  for (const SceneObject& object : world.scene.objects) {
    if (object.instance_id == 0) continue;
    // Vehicles keep 3.5 m (moving) or 1 m + their half diagonal (parked) from the camera path;
    // people 1.5 m (walking) or 0.8 m + their half diagonal (standing).
    const double min_distance = object.object_class == ObjectClass::kVehicle ? 3.0 : 1.2;
    for (TimeNs t = path.range.begin; t <= path.range.end; t += 50 * kNsPerMillisecond) {
      const auto pose = object.T_w_o(t);
      if (!pose) continue;
      const Eigen::Vector2d camera = path.T_w_c(t).t.head<2>();
      EXPECT_GT((pose->t.head<2>() - camera).norm(), min_distance)
          << "instance " << object.instance_id << " at " << nsToSeconds(t) << " s";
    }
  }
}

TEST(WorldBuilderTest, IndoorWorldsHavePeopleOnlyAndEveryTextureIndexIsValid) {
  const World world =
      buildWorld(coarseWorld(SceneType::kIndoor, DynamicLevel::kMid), straightDrive());
  for (const auto& agent : world.agents) {
    EXPECT_EQ(agent.object_class, ObjectClass::kPedestrian);
  }
  for (const SceneObject& object : world.scene.objects) {
    for (const Quad& quad : object.quads) {
      EXPECT_GE(quad.texture, 0);
      EXPECT_LT(quad.texture, static_cast<int>(world.scene.textures.size()));
    }
  }
}

TEST(WorldBuilderTest, SameSeedSameWorld) {
  const CameraPath path = straightDrive();
  const World a = buildWorld(coarseWorld(SceneType::kParking, DynamicLevel::kMid), path);
  const World b = buildWorld(coarseWorld(SceneType::kParking, DynamicLevel::kMid), path);
  ASSERT_EQ(a.agents.size(), b.agents.size());
  for (std::size_t i = 0; i < a.agents.size(); ++i) {
    EXPECT_EQ(a.agents[i].t_begin_ns, b.agents[i].t_begin_ns);
    EXPECT_EQ(a.agents[i].object_class, b.agents[i].object_class);
  }
}

/// Indices of the textures the static world (instance 0) or the agents use.
std::set<int> texturesOf(const World& world, bool agents) {
  std::set<int> textures;
  for (const SceneObject& object : world.scene.objects) {
    if ((object.instance_id != 0) != agents) continue;
    for (const Quad& quad : object.quads)
      textures.insert(quad.texture);
  }
  return textures;
}

double deviationOf(const Texture& texture) {
  cv::Scalar mean, deviation;
  cv::meanStdDev(texture.image(), mean, deviation);
  return deviation[0];
}

/// The parking world of `level` on straightDrive() with the usual options and with `change`.
std::pair<World, World> usualAndChangedParking(DynamicLevel level,
                                               const std::function<void(WorldOptions&)>& change) {
  const CameraPath path = straightDrive();
  WorldOptions options = coarseWorld(SceneType::kParking, level);
  World usual = buildWorld(options, path);
  change(options);
  return {std::move(usual), buildWorld(options, path)};
}

TEST(WorldBuilderTest, BackgroundContrastWeakensTheStaticWorldOnly) {
  const auto [usual, weak] = usualAndChangedParking(
      DynamicLevel::kMid, [](WorldOptions& options) { options.background_contrast = 0.3; });
  ASSERT_EQ(weak.scene.textures.size(), usual.scene.textures.size());
  ASSERT_EQ(weak.agents.size(), usual.agents.size());
  const std::set<int> background = texturesOf(usual, false);
  const std::set<int> agents = texturesOf(usual, true);
  ASSERT_FALSE(background.empty());
  ASSERT_FALSE(agents.empty());
  for (const int i : background) {
    const auto k = static_cast<std::size_t>(i);
    EXPECT_NEAR(deviationOf(weak.scene.textures[k]) / deviationOf(usual.scene.textures[k]), 0.3,
                0.02)
        << "texture " << i;
  }
  for (const int i : agents) {
    const auto k = static_cast<std::size_t>(i);
    EXPECT_EQ(
        cv::norm(weak.scene.textures[k].image(), usual.scene.textures[k].image(), cv::NORM_INF),
        0.0)
        << "texture " << i;
  }
}

TEST(WorldBuilderTest, ParkedDensityFillsTheLotWithStaticAgents) {
  const auto [usual, full] = usualAndChangedParking(
      DynamicLevel::kNone, [](WorldOptions& options) { options.parked_density = 4.0; });
  // 100 m of path, a place tried every 5 m (usual: 20 agents) or every 1.25 m (full: 51; a
  // place overlapping an earlier agent is skipped).
  const int parked = countAgents(usual, false);
  EXPECT_GE(parked, 15);
  EXPECT_GE(countAgents(full, false), 2 * parked);
  EXPECT_EQ(countAgents(full, true), 0);
}

TEST(WorldBuilderTest, TextureVarietyRepeatsTheStaticTexturesOnTheSameLayout) {
  const auto [usual, aliased] = usualAndChangedParking(
      DynamicLevel::kMid, [](WorldOptions& options) { options.texture_variety = 2; });
  const std::vector<Quad>& surfaces = usual.scene.objects.front().quads;
  const std::vector<Quad>& aliased_surfaces = aliased.scene.objects.front().quads;
  ASSERT_EQ(aliased_surfaces.size(), surfaces.size());
  for (std::size_t i = 0; i < surfaces.size(); ++i) {
    EXPECT_EQ(aliased_surfaces[i].origin, surfaces[i].origin) << "surface " << i;
    EXPECT_EQ(aliased_surfaces[i].edge_u, surfaces[i].edge_u) << "surface " << i;
  }
  ASSERT_EQ(aliased.agents.size(), usual.agents.size());
  // Usually every surface has its own texture; parking's static surfaces are of three kinds
  // (ground, facades at 2 cm texels, clutter at 1 cm), which now share two textures each.
  EXPECT_EQ(texturesOf(usual, false).size(), surfaces.size());
  const std::set<int> shared = texturesOf(aliased, false);
  EXPECT_EQ(shared.size(), 6u);
  ASSERT_GT(surfaces.size(), 50u);
  // Each surface shows the top-left of its texture, which covers the largest of them.
  for (const Quad& quad : aliased_surfaces) {
    const Texture& texture = aliased.scene.textures.at(static_cast<std::size_t>(quad.texture));
    EXPECT_GE(texture.image().cols * texture.texelSizeM(), quad.edge_u.norm() - 1e-9);
    EXPECT_GE(texture.image().rows * texture.texelSizeM(), quad.edge_v.norm() - 1e-9);
  }
  // The agents look as they did.
  ASSERT_EQ(aliased.scene.objects.size(), usual.scene.objects.size());
  for (std::size_t i = 1; i < usual.scene.objects.size(); ++i) {
    const std::vector<Quad>& quads = usual.scene.objects[i].quads;
    ASSERT_EQ(aliased.scene.objects[i].quads.size(), quads.size());
    for (std::size_t j = 0; j < quads.size(); ++j) {
      const auto texture = [j](const World& world, std::size_t object) {
        const int index = world.scene.objects[object].quads[j].texture;
        return world.scene.textures.at(static_cast<std::size_t>(index)).image();
      };
      EXPECT_EQ(cv::norm(texture(aliased, i), texture(usual, i), cv::NORM_INF), 0.0)
          << "agent " << i << ", quad " << j;
    }
  }
  WorldOptions options;
  options.texture_variety = -1;
  EXPECT_THROW(options.validate(), OptionError);
}

TEST(WorldBuilderTest, BackgroundContrastAndParkedDensityOutOfRangeAreErrors) {
  for (const double contrast : {0.0, -0.1, 1.5}) {
    WorldOptions options;
    options.background_contrast = contrast;
    EXPECT_THROW(options.validate(), OptionError) << contrast;
  }
  for (const double density : {0.0, 11.0}) {
    WorldOptions options;
    options.parked_density = density;
    EXPECT_THROW(options.validate(), OptionError) << density;
  }
}

TEST(WorldBuilderTest, ParsesNamesAndRejectsUnknownOnes) {
  EXPECT_EQ(parseSceneType("parking"), SceneType::kParking);
  EXPECT_EQ(parseDynamicLevel("high"), DynamicLevel::kHigh);
  EXPECT_EQ(movingAgentTarget(DynamicLevel::kMid), 5);
  EXPECT_THROW(parseSceneType("desert"), OptionError);
  EXPECT_THROW(parseDynamicLevel("extreme"), OptionError);
}

}  // namespace
}  // namespace superdyna::sim
