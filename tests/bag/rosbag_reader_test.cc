// RosbagReader on the real bags of ../shared/data/rosbag (uncompressed, bz2 and lz4 chunks,
// unsorted chunks): topics, types and message counts as ROS's own Python reader (python3-rosbag,
// bag_topics.py) sees them, images decoded at their size, IMU samples with their values.

#include "superdyna/bag/rosbag_reader.h"

#include <gtest/gtest.h>

#include <array>
#include <cstdio>
#include <memory>
#include <sstream>
#include <string>

#include "superdyna/core/error.h"
#include "support/test_support.h"

namespace superdyna::bag {
namespace {

namespace fs = std::filesystem;

/// What bag_topics.py prints for a bag (empty when python3-rosbag is missing).
std::string pythonView(const fs::path& bag) {
  const std::string command = std::string("/usr/bin/python3 ") + SUPERDYNA_TEST_DIR +
                              "/bag_topics.py '" + bag.string() + "' 2>&1";
  std::unique_ptr<FILE, int (*)(FILE*)> pipe(popen(command.c_str(), "r"), pclose);
  std::string out;
  std::array<char, 4096> buffer{};
  while (pipe && fgets(buffer.data(), buffer.size(), pipe.get()))
    out += buffer.data();
  return out;
}

/// The same lines from RosbagReader.
std::string readerView(const RosbagReader& reader) {
  std::ostringstream out;
  for (const BagTopic& topic : reader.topics())
    out << topic.name << '\t' << topic.type << '\t' << topic.messages << '\n';
  for (const BagTopic& topic : reader.topics()) {
    if (topic.type == "sensor_msgs/Imu") {
      const sensors::ImuSample s = reader.imuSamples(topic.name).front();
      char line[512];
      std::snprintf(line, sizeof(line), "imu\t%s\t%lld %.17g %.17g %.17g %.17g %.17g %.17g\n",
                    topic.name.c_str(), static_cast<long long>(s.t_ns), s.gyro.x(), s.gyro.y(),
                    s.gyro.z(), s.accel.x(), s.accel.y(), s.accel.z());
      out << line;
    } else if (topic.type == "sensor_msgs/Image") {
      bool first = true;
      reader.forEachImage(topic.name, [&](std::size_t, const BagImage& image) {
        if (first)
          out << "image\t" << topic.name << '\t' << image.image.cols << ' ' << image.image.rows
              << '\n';
        first = false;
      });
    }
  }
  return out.str();
}

TEST(RosbagReader, EveryBagReadsAsRosPythonReaderReadsIt) {
  SUPERDYNA_REQUIRE_SHARED(bags, "data/rosbag");
  if (pythonView(bags / "serpent_imu_up_10msg_none.bag").find("Traceback") != std::string::npos) {
    const char* message = "python3-rosbag is not installed (scripts/setup.sh installs it)";
    if (test::sharedDataRequired()) GTEST_FAIL() << message;
    GTEST_SKIP() << message;
  }
  int checked = 0;
  for (const auto& entry : fs::directory_iterator(bags)) {
    if (entry.path().extension() != ".bag") continue;
    SCOPED_TRACE(entry.path().filename().string());
    const RosbagReader reader = RosbagReader::open(entry.path());
    // Python prints floats with repr (shortest round trip), we with %.17g: compare numbers.
    std::istringstream expected(pythonView(entry.path())), actual(readerView(reader));
    std::string e, a;
    while (std::getline(expected, e)) {
      ASSERT_TRUE(std::getline(actual, a)) << "missing line: " << e;
      if (e.rfind("imu\t", 0) == 0) {
        std::istringstream es(e.substr(e.rfind('\t') + 1)), as(a.substr(a.rfind('\t') + 1));
        long long et = 0, at = 0;
        es >> et;
        as >> at;
        EXPECT_EQ(at, et);
        for (int i = 0; i < 6; ++i) {
          double ev = 0, av = 0;
          es >> ev;
          as >> av;
          EXPECT_EQ(av, ev) << e;
        }
      } else {
        EXPECT_EQ(a, e);
      }
    }
    EXPECT_FALSE(std::getline(actual, a)) << "extra line: " << a;
    ++checked;
  }
  EXPECT_EQ(checked, 7);
}

TEST(RosbagReader, DecodesRawAndCompressedImages) {
  SUPERDYNA_REQUIRE_SHARED(bags, "data/rosbag");
  const RosbagReader numpy = RosbagReader::open(bags / "ros_numpy_image_compressedimage_none.bag");
  cv::Mat raw, png;
  numpy.forEachImage("/image", [&](std::size_t, const BagImage& image) {
    EXPECT_EQ(image.encoding, "rgb8");
    raw = image.image;
  });
  numpy.forEachImage("/compressedimage", [&](std::size_t, const BagImage& image) {
    EXPECT_EQ(image.encoding, "png");
    png = image.image;
  });
  ASSERT_EQ(raw.size(), cv::Size(360, 240));
  ASSERT_EQ(raw.type(), CV_8UC3);
  // The fixture's compressed message is a PNG of 2 x 2 pixels (82 bytes), not the raw image.
  EXPECT_EQ(png.size(), cv::Size(2, 2));
  EXPECT_EQ(toGray8(raw).type(), CV_8UC1);

  const RosbagReader realsense =
      RosbagReader::open(bags / "librealsense_single_depth_color_640x480_lz4.bag");
  int depth_frames = 0;
  realsense.forEachImage("/device_0/sensor_0/Depth_0/image/data",
                         [&](std::size_t, const BagImage& image) {
                           EXPECT_EQ(image.encoding, "mono16");
                           EXPECT_EQ(image.image.type(), CV_16UC1);
                           EXPECT_EQ(image.image.size(), cv::Size(640, 480));
                           EXPECT_GT(cv::countNonZero(image.image), 1000);
                           ++depth_frames;
                         });
  EXPECT_EQ(depth_frames, 2);
}

TEST(RosbagReader, ErrorsNameTheBagAndTopic) {
  SUPERDYNA_REQUIRE_SHARED(bags, "data/rosbag");
  const fs::path file = bags / "serpent_imu_up_10msg_none.bag";
  const RosbagReader reader = RosbagReader::open(file);
  test::expectError([&] { reader.imuSamples("/cam0/image_raw"); },
                    {file.string(), "no topic '/cam0/image_raw'", "/imu"});
  test::expectError([&] { reader.forEachImage("/imu", [](std::size_t, const BagImage&) {}); },
                    {file.string(), "/imu holds sensor_msgs/Imu"});
  test::expectError([&] { RosbagReader::open(bags / "no-such.bag"); },
                    {"no-such.bag", "not found"});
  const test::ScratchDir dir("bag_not_a_bag");
  const fs::path text = dir / "text.bag";
  test::writeFile(text, "not a bag\n");
  test::expectError([&] { RosbagReader::open(text); }, {"text.bag", "not a readable ROS 1 bag"});
}

}  // namespace
}  // namespace superdyna::bag
