// Sequences with photometric challenges: the exposure gains written to photometric.csv are the
// schedule's and are applied to the images exactly; blur + illumination stay deterministic.

#include <gtest/gtest.h>

#include <algorithm>
#include <opencv2/imgcodecs.hpp>
#include <string>

#include "superdyna/core/error.h"
#include "superdyna/io/text_table.h"
#include "superdyna/sim/sequence_generator.h"
#include "support/test_support.h"

namespace superdyna::sim {
namespace {

namespace fs = std::filesystem;
using test::ScratchDir;

SimulationOptions shortSequence(const fs::path& out) {
  SimulationOptions options;
  options.output_dir = out;
  options.motion.duration_s = 0.5;
  options.world.scene = SceneType::kIndoor;
  options.world.dynamic = DynamicLevel::kLow;
  options.landmark_count = 0;
  options.seed = 11;
  return options;
}

/// Every effect, fast enough to show several levels within half a second.
SimulationOptions withIllumination(SimulationOptions options) {
  setIlluminationModes("all", &options.illumination);
  options.illumination.drift_period_s = 1.0;
  options.illumination.step_interval_s = 0.2;
  options.illumination.stereo_gain_ratio = 1.2;
  return options;
}

SimulationOptions withBlur(SimulationOptions options) {
  options.motion_blur_exposure_s = 0.01;
  options.motion_blur_max_samples = 5;
  return options;
}

class PhotometricSequenceTest : public ::testing::Test {
 protected:
  static void SetUpTestSuite() {
    dir_ = new ScratchDir("photometric_sequence");
    generateSequence(shortSequence(dir_->path() / "clean"));
    generateSequence(withIllumination(shortSequence(dir_->path() / "lit")));
    blurred_ = generateSequence(withBlur(withIllumination(shortSequence(dir_->path() / "both"))));
  }
  static void TearDownTestSuite() {
    delete dir_;
    dir_ = nullptr;
  }

  static ScratchDir* dir_;
  static SimulationSummary blurred_;
};

ScratchDir* PhotometricSequenceTest::dir_ = nullptr;
SimulationSummary PhotometricSequenceTest::blurred_;

cv::Mat readGray(const fs::path& file) {
  cv::Mat image = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
  EXPECT_FALSE(image.empty()) << file;
  return image;
}

TEST_F(PhotometricSequenceTest, ImagesCarryTheScheduledGainsExactly) {
  const SimulationOptions options = withIllumination(shortSequence(""));
  const auto rows =
      io::readTextRows(dir_->path() / "lit/mav0/photometric.csv", io::Delimiter::kComma);
  ASSERT_EQ(rows.size(), 11u);  // 0.5 s at 20 Hz
  const TimeNs t0 = std::stoll(rows.front().fields[0]);
  const IlluminationSchedule schedule(options.illumination, options.seed, t0);
  double min_gain = 10.0, max_gain = 0.0;
  for (const auto& row : rows) {
    const TimeNs t = std::stoll(row.fields[0]);
    const std::string name = row.fields[0] + ".png";
    for (const int cam : {0, 1}) {
      const double gain = std::stod(row.fields[1 + static_cast<std::size_t>(cam)]);
      EXPECT_NEAR(gain, schedule.gain(cam, t), 1e-8);
      min_gain = std::min(min_gain, gain);
      max_gain = std::max(max_gain, gain);
      const std::string folder = "mav0/cam" + std::to_string(cam) + "/data/";
      const cv::Mat clean = readGray(dir_->path() / "clean" / folder / name);
      cv::Mat lit = readGray(dir_->path() / "lit" / folder / name);
      // Pixels the gain does not clip, with a margin for the noise (the same in both images).
      const cv::Mat unclipped =
          (clean >= std::max(20.0, 10.0 / gain)) & (clean <= 245.0 / gain - 2.0);
      ASSERT_GT(cv::countNonZero(unclipped), 20000) << name << " cam" << cam;
      const double ratio =
          cv::sum(lit.setTo(0, ~unclipped))[0] / cv::sum(clean.clone().setTo(0, ~unclipped))[0];
      EXPECT_NEAR(ratio, gain, 0.003 * gain) << name << " cam" << cam;
    }
  }
  // The schedule really varies: steps, drift and flicker over half a second.
  EXPECT_LT(min_gain, 0.8);
  EXPECT_GT(max_gain, 1.3);
}

TEST_F(PhotometricSequenceTest, BlurAndIlluminationAreDeterministicAndRecorded) {
  generateSequence(withBlur(withIllumination(shortSequence(dir_->path() / "again"))));
  std::size_t compared = 0;
  const fs::path first = dir_->path() / "both";
  for (const auto& entry : fs::recursive_directory_iterator(first)) {
    if (!entry.is_regular_file()) continue;
    const fs::path other = dir_->path() / "again" / fs::relative(entry.path(), first);
    ASSERT_TRUE(fs::exists(other)) << other;
    ASSERT_EQ(test::readFile(entry.path()), test::readFile(other)) << other;
    ++compared;
  }
  EXPECT_GT(compared, 40u);  // 11 frames x (2 images + 2 masks) + tables
  EXPECT_GT(blurred_.mean_blur_samples, 1.0);
  EXPECT_LE(blurred_.mean_blur_samples, 5.0);
  EXPECT_GT(blurred_.max_exposure_motion_px, 0.0);
  const std::string yaml = test::readFile(first / "simulation.yaml");
  EXPECT_NE(yaml.find("exposure_ms: 10\n"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("effects: drift,steps,flicker\n"), std::string::npos) << yaml;
  EXPECT_NE(yaml.find("stereo_gain_ratio: 1.2\n"), std::string::npos) << yaml;
  // Without any effect there is no photometric table, as before these options existed.
  EXPECT_FALSE(fs::exists(dir_->path() / "clean/mav0/photometric.csv"));
  // The blurred images differ from the sharp ones with the same gains, the masks do not.
  const auto rows = io::readTextRows(first / "mav0/photometric.csv", io::Delimiter::kComma);
  const std::string name = rows[5].fields[0] + ".png";
  EXPECT_GT(cv::norm(readGray(first / "mav0/cam0/data" / name),
                     readGray(dir_->path() / "lit/mav0/cam0/data" / name), cv::NORM_L1),
            0.0);
  EXPECT_EQ(test::readFile(first / "mav0/cam0/mask" / name),
            test::readFile(dir_->path() / "lit/mav0/cam0/mask" / name));
}

TEST(PhotometricSequenceOptionsTest, RejectsBadPhotometricOptions) {
  ScratchDir dir("photometric_refuse");
  SimulationOptions options = shortSequence(dir.path() / "x");
  options.motion_blur_exposure_s = 0.2;
  EXPECT_THROW(generateSequence(options), OptionError);
  options = shortSequence(dir.path() / "x");
  options.motion_blur_samples = -1;
  EXPECT_THROW(generateSequence(options), OptionError);
  options = shortSequence(dir.path() / "x");
  options.illumination.flicker_amplitude = 0.7;
  EXPECT_THROW(generateSequence(options), OptionError);
}

}  // namespace
}  // namespace superdyna::sim
