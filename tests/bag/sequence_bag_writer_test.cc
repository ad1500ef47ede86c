// writeViodeBag on a simulated sequence: read back by RosbagReader and by ROS's Python reader,
// every image, segmentation image, IMU sample and ground-truth state is the folder's.

#include "superdyna/bag/sequence_bag_writer.h"

#include <gtest/gtest.h>

#include <opencv2/imgcodecs.hpp>

#include "superdyna/bag/rosbag_reader.h"
#include "superdyna/core/error.h"
#include "superdyna/io/calibration.h"
#include "superdyna/io/euroc_dataset.h"
#include "support/generated_sequence.h"
#include "support/test_support.h"

namespace superdyna::bag {
namespace {

namespace fs = std::filesystem;

const fs::path& coloursSequence() {
  sim::SimulationOptions options =
      test::flightOptions(1.0, sim::SceneType::kStreet, sim::DynamicLevel::kHigh, 11);
  options.semantic_color = true;
  return test::generatedSequence("bag_writer_street", options);
}

std::size_t countOf(const RosbagReader& reader, const std::string& topic) {
  return reader.topic(topic).messages;
}

TEST(SequenceBagWriter, TheBagHoldsTheFoldersFramesImuAndGroundTruth) {
  const fs::path& sequence = coloursSequence();
  const io::EurocDataset dataset = io::EurocDataset::open(sequence);
  const test::ScratchDir dir("bag_writer");
  const fs::path file = dir / "street.bag";
  const std::map<std::string, std::size_t> counts = writeViodeBag(sequence, file, "lz4");
  const std::size_t frames = dataset.stereoFrames().size();
  ASSERT_GT(frames, 10u);
  EXPECT_EQ(counts.at("/cam0/image_raw"), frames);
  EXPECT_EQ(counts.at("/cam1/segmentation"), frames);
  EXPECT_FALSE(fs::exists(file.string() + ".partial"));

  const RosbagReader reader = RosbagReader::open(file);
  ASSERT_EQ(reader.topics().size(), 6u);
  EXPECT_EQ(countOf(reader, "/cam0/image_raw"), frames);
  EXPECT_EQ(countOf(reader, "/cam1/image_raw"), frames);
  EXPECT_EQ(countOf(reader, "/cam0/segmentation"), frames);
  EXPECT_EQ(countOf(reader, "/imu0"), dataset.imu().size());
  EXPECT_EQ(countOf(reader, "/odometry"), dataset.groundTruth().size());
  EXPECT_EQ(reader.topic("/odometry").type, "nav_msgs/Odometry");

  int differing = 0;
  reader.forEachImage("/cam1/image_raw", [&](std::size_t i, const BagImage& image) {
    const io::StereoFrameRef& ref = dataset.stereoFrames()[i];
    EXPECT_EQ(image.t_ns, ref.t_ns);
    EXPECT_EQ(image.encoding, "mono8");
    differing +=
        cv::norm(image.image, io::decodePngFile(ref.cam1, cv::IMREAD_GRAYSCALE), cv::NORM_INF) != 0;
  });
  reader.forEachImage("/cam0/segmentation", [&](std::size_t i, const BagImage& image) {
    const fs::path png =
        dataset.root() / "cam0" / "segmentation" / dataset.stereoFrames()[i].cam0.filename();
    EXPECT_EQ(image.encoding, "bgr8");
    differing += cv::norm(image.image, io::decodePngFile(png, cv::IMREAD_COLOR), cv::NORM_INF) != 0;
  });
  EXPECT_EQ(differing, 0);
  const std::vector<sensors::ImuSample> imu = reader.imuSamples("/imu0");
  ASSERT_EQ(imu.size(), dataset.imu().size());
  for (std::size_t i = 0; i < imu.size(); ++i) {
    EXPECT_EQ(imu[i].t_ns, dataset.imu()[i].t_ns);
    EXPECT_EQ(imu[i].gyro, dataset.imu()[i].gyro);
    EXPECT_EQ(imu[i].accel, dataset.imu()[i].accel);
  }
}

TEST(SequenceBagWriter, NeverOverwritesAFile) {
  const fs::path& sequence = coloursSequence();
  const test::ScratchDir dir("bag_writer_exists");
  const fs::path file = dir / "mine.bag";
  test::writeFile(file, "keep me\n");
  test::expectError([&] { writeViodeBag(sequence, file, "none"); }, {"mine.bag", "exists already"});
  EXPECT_EQ(test::readFile(file), "keep me\n");
  test::expectError<OptionError>([&] { writeViodeBag(sequence, dir / "other.bag", "zip"); },
                                 {"compression", "expected none, bz2 or lz4"});
  EXPECT_FALSE(fs::exists(dir / "other.bag"));
}

}  // namespace
}  // namespace superdyna::bag
