// A simulated sequence written as a VIODE-layout bag (writeViodeBag) and served by openBagSource
// gives the folder's frames, and the deterministic pipeline the same trajectory, bit for bit.

#include "superdyna/bag/bag_source.h"

#include <fmt/format.h>
#include <gtest/gtest.h>

#include "superdyna/bag/bag_segmenter.h"
#include "superdyna/bag/bag_writer.h"
#include "superdyna/bag/sequence_bag_writer.h"
#include "superdyna/core/error.h"
#include "superdyna/io/euroc_dataset.h"
#include "superdyna/system/system.h"
#include "support/generated_sequence.h"
#include "support/test_support.h"

namespace superdyna::bag {
namespace {

namespace fs = std::filesystem;

const fs::path& streetSequence() {
  sim::SimulationOptions options =
      test::flightOptions(4.0, sim::SceneType::kStreet, sim::DynamicLevel::kMid, 21);
  options.semantic_color = true;
  return test::generatedSequence("bag_source_street", options);
}

Trajectory runDeterministic(io::DatasetSource& source, system::SensorMode mode,
                            std::unique_ptr<semantics::Segmenter> segmenter = nullptr) {
  system::SystemOptions options;
  options.mode = mode;
  options.deterministic = true;
  if (segmenter) options.tracker.dynamic.mode = dynamic::DynamicMode::kSemanticGeometric;
  system::System slam(options, source.camera0(), source.camera1(), source.imu(),
                      std::move(segmenter));
  slam.run(source, {});
  return slam.trajectory();
}

void expectSameTrajectory(const Trajectory& actual, const Trajectory& expected) {
  ASSERT_GT(expected.size(), 50u);
  ASSERT_EQ(actual.size(), expected.size());
  for (std::size_t i = 0; i < expected.size(); ++i) {
    ASSERT_EQ(actual[i].t_ns, expected[i].t_ns);
    ASSERT_EQ(actual[i].T_w_x.t, expected[i].T_w_x.t) << "frame " << i;
    ASSERT_EQ(actual[i].T_w_x.q.coeffs(), expected[i].T_w_x.q.coeffs()) << "frame " << i;
  }
}

semantics::SegmenterOptions datasetSegmentation(const std::string& format) {
  semantics::SegmenterOptions options;
  options.segmenter = "dataset";
  options.dataset_format = format;
  return options;
}

void expectSameFrames(io::DatasetSource& folder, io::DatasetSource& bag) {
  ASSERT_EQ(bag.size(), folder.size());
  EXPECT_EQ(bag.groundTruth().size(), folder.groundTruth().size());
  while (const auto expected = folder.next()) {
    const auto actual = bag.next();
    ASSERT_TRUE(actual.has_value());
    ASSERT_EQ(actual->t_ns, expected->t_ns);
    EXPECT_EQ(cv::norm(actual->image0, expected->image0, cv::NORM_INF), 0.0);
    EXPECT_EQ(cv::norm(actual->image1, expected->image1, cv::NORM_INF), 0.0);
    ASSERT_EQ(actual->imu.size(), expected->imu.size());
    for (std::size_t i = 0; i < expected->imu.size(); ++i) {
      EXPECT_EQ(actual->imu[i].t_ns, expected->imu[i].t_ns);
      EXPECT_EQ(actual->imu[i].gyro, expected->imu[i].gyro);
      EXPECT_EQ(actual->imu[i].accel, expected->imu[i].accel);
    }
    ASSERT_EQ(actual->T_w_b_gt.has_value(), expected->T_w_b_gt.has_value());
    if (expected->T_w_b_gt) {
      EXPECT_EQ(actual->T_w_b_gt->t, expected->T_w_b_gt->t);
    }
  }
  EXPECT_FALSE(bag.next().has_value());
}

TEST(BagSource, ServesTheFramesOfTheFolderItWasWrittenFrom) {
  const fs::path& sequence = streetSequence();
  const test::ScratchDir dir("bag_source_frames");
  const fs::path file = dir / "street.bag";
  writeViodeBag(sequence, file, "lz4");
  io::DatasetSourceOptions options;
  options.first_frame = 3;
  options.max_frames = 50;
  const auto folder = io::openDataset(io::DatasetKind::kEuroc, sequence, options);
  const auto bag = openBagSource(file, sequence, bagTopicsPreset("viode"), options);
  EXPECT_EQ(bag->camera0().fx, folder->camera0().fx);
  EXPECT_EQ(bag->imu()->gyroscope_noise_density, folder->imu()->gyroscope_noise_density);
  expectSameFrames(*folder, *bag);
}

TEST(BagSource, DeterministicStereoInertialRunEqualsTheFoldersBitForBit) {
  const fs::path& sequence = streetSequence();
  const test::ScratchDir dir("bag_source_run");
  const fs::path file = dir / "street.bag";
  writeViodeBag(sequence, file, "none");
  const io::DatasetSourceOptions options;
  const auto folder = io::openDataset(io::DatasetKind::kEuroc, sequence, options);
  const auto bag = openBagSource(file, sequence / "mav0", bagTopicsPreset("viode"), options);
  const Trajectory expected = runDeterministic(*folder, system::SensorMode::kStereoInertial);
  const Trajectory actual = runDeterministic(*bag, system::SensorMode::kStereoInertial);
  expectSameTrajectory(actual, expected);
}

TEST(BagSource, SegmentationTopicsGiveTheFoldersInstanceMasks) {
  const fs::path& sequence = streetSequence();
  const test::ScratchDir dir("bag_source_segmentation");
  const fs::path file = dir / "street.bag";
  writeViodeBag(sequence, file, "none");
  const auto from_bag = makeBagSegmenter(datasetSegmentation("color"), file, sequence);
  const auto from_masks = semantics::makeSegmenter(datasetSegmentation("masks"), sequence);
  ASSERT_TRUE(from_bag->idsNameObjects());
  const auto source = io::openDataset(io::DatasetKind::kEuroc, sequence, {});
  int frames = 0, differing = 0, objects = 0;
  while (const auto frame = source->next()) {
    for (int camera = 0; camera < 2; ++camera) {
      const cv::Mat& image = camera == 0 ? frame->image0 : frame->image1;
      const semantics::Segmentation a = from_bag->segment(image, frame->t_ns, camera);
      const semantics::Segmentation b = from_masks->segment(image, frame->t_ns, camera);
      differing += cv::countNonZero(a.ids != b.ids);
      objects += static_cast<int>(a.instances.size());
      EXPECT_EQ(a.instances.size(), b.instances.size());
    }
    ++frames;
  }
  EXPECT_GT(frames, 50);
  EXPECT_GT(objects, frames);  // movers and parked cars in view
  EXPECT_EQ(differing, 0);

  // The same labels through the whole pipeline, with the moving-object test: the same trajectory.
  const auto folder = io::openDataset(io::DatasetKind::kEuroc, sequence, {});
  const auto bag = openBagSource(file, sequence, bagTopicsPreset("viode"), {});
  expectSameTrajectory(
      runDeterministic(*bag, system::SensorMode::kStereoInertial,
                       makeBagSegmenter(datasetSegmentation("color"), file, sequence)),
      runDeterministic(*folder, system::SensorMode::kStereoInertial,
                       semantics::makeSegmenter(datasetSegmentation("masks"), sequence)));
  test::expectError<OptionError>(
      [&] { makeBagSegmenter(datasetSegmentation("masks"), file, sequence); },
      {"semantics.dataset_format", "use color"});
}

TEST(BagSource, ErrorsNameWhatIsMissing) {
  const fs::path& sequence = streetSequence();
  const test::ScratchDir dir("bag_source_errors");
  const fs::path file = dir / "street.bag";
  writeViodeBag(sequence, file, "none");
  test::expectError([&] { openBagSource(file, dir.path(), BagTopics{}, {}); },
                    {dir.path().string(), "no cam0/sensor.yaml"});
  BagTopics topics;
  topics.imu = "/imu";
  test::expectError([&] { openBagSource(file, sequence, topics, {}); },
                    {file.string(), "no topic '/imu'", "/imu0"});
  test::expectError<OptionError>([&] { bagTopicsPreset("kalibr"); }, {"--topics", "kalibr"});
}

TEST(BagSource, OpenlorisLayoutPublishesTheImuApartAndTheSourceMergesItBack) {
  const fs::path& sequence = streetSequence();
  const test::ScratchDir dir("bag_source_openloris");
  const fs::path file = dir / "openloris.bag";
  const auto counts = writeOpenlorisBag(sequence, file, "lz4");
  io::DatasetSourceOptions mono_inertial;
  mono_inertial.stereo = false;
  const auto folder = io::openDataset(io::DatasetKind::kEuroc, sequence, mono_inertial);
  const std::vector<sensors::ImuSample> imu = io::EurocDataset::open(sequence).imu();
  EXPECT_EQ(counts.at("/d400/color/image_raw"), folder->size());
  EXPECT_EQ(counts.at("/d400/gyro/sample"), imu.size());
  const TimeNs accel_span = imu.back().t_ns - imu.front().t_ns - 2 * kNsPerMillisecond;
  EXPECT_EQ(counts.at("/d400/accel/sample"),
            static_cast<std::size_t>(accel_span / (16 * kNsPerMillisecond)) + 1);
  EXPECT_EQ(counts.count("/odometry"), 0u);

  const fs::path ground_truth = sequence / "mav0" / "state_groundtruth_estimate0" / "data.csv";
  const auto bag =
      openBagSource(file, sequence, bagTopicsPreset("openloris"), mono_inertial, ground_truth);
  EXPECT_FALSE(bag->camera1().has_value());
  const Trajectory folder_truth = folder->groundTruth();
  std::map<TimeNs, sensors::FrameBundle> folder_frames;
  while (auto frame = folder->next())
    folder_frames.emplace(frame->t_ns, std::move(*frame));
  std::size_t frames = 0, samples = 0;
  double accel_error = 0.0;
  while (const auto actual = bag->next()) {
    const sensors::FrameBundle& expected = folder_frames.at(actual->t_ns);
    ++frames;
    EXPECT_EQ(cv::norm(actual->image0, expected.image0, cv::NORM_INF), 0.0);  // rgb8 -> grey
    ASSERT_TRUE(actual->T_w_b_gt.has_value());
    EXPECT_LT((actual->T_w_b_gt->t - expected.T_w_b_gt->t).norm(), 1e-9);
    if (frames == 1) continue;  // its IMU interval starts before the first served frame
    ASSERT_EQ(actual->imu.size(), expected.imu.size()) << "frame at " << actual->t_ns;
    for (std::size_t i = 0; i < expected.imu.size(); ++i) {
      EXPECT_EQ(actual->imu[i].t_ns, expected.imu[i].t_ns);
      EXPECT_EQ(actual->imu[i].gyro, expected.imu[i].gyro);
      accel_error += (actual->imu[i].accel - expected.imu[i].accel).norm();
      ++samples;
    }
  }
  // Only the first and the last frame, outside the accelerometer's time range, are left out; the
  // ground truth is the file's over the frames served.
  EXPECT_EQ(frames + 2, folder_frames.size());
  EXPECT_EQ(bag->groundTruth().size(),
            std::count_if(folder_truth.begin(), folder_truth.end(), [&](const StampedPose& p) {
              return p.t_ns + kNsPerMillisecond >= std::next(folder_frames.begin())->first &&
                     p.t_ns <= std::prev(folder_frames.end(), 2)->first + kNsPerMillisecond;
            }));
  ASSERT_GT(samples, 500u);
  // Resampled at 62.5 Hz and interpolated back: the motion's acceleration is kept, the sensor
  // noise (about 0.03 m/s^2 per axis per sample here) is smoothed.
  EXPECT_LT(accel_error / static_cast<double>(samples), 0.1);

  io::DatasetSourceOptions stereo = mono_inertial;
  stereo.stereo = true;
  test::expectError<OptionError>(
      [&] { openBagSource(file, sequence, bagTopicsPreset("openloris"), stereo); },
      {"--topics", "no second camera"});
}

/// A VINS-Fusion config file describing the same rig as the folder's sensor.yaml files.
fs::path writeVinsConfig(const fs::path& dir, const io::DatasetSource& folder) {
  const auto matrix = [](const SE3d& T) {
    const Eigen::Matrix4d M = T.matrix();
    std::string data;
    for (int r = 0; r < 4; ++r)
      for (int c = 0; c < 4; ++c)
        data += fmt::format("{}{:.17g}", data.empty() ? "" : ", ", M(r, c));
    return fmt::format("!!opencv-matrix\n   rows: 4\n   cols: 4\n   dt: d\n   data: [{}]\n", data);
  };
  const sensors::CameraCalibration* cameras[2] = {&folder.camera0(), &*folder.camera1()};
  for (int i = 0; i < 2; ++i) {
    const sensors::CameraCalibration& c = *cameras[i];
    test::writeFile(dir / fmt::format("cam{}.yaml", i),
                    fmt::format("%YAML:1.0\n---\nmodel_type: PINHOLE\nimage_width: {}\n"
                                "image_height: {}\ndistortion_parameters:\n   k1: 0.0\n"
                                "   k2: 0.0\n   p1: 0.0\n   p2: 0.0\nprojection_parameters:\n"
                                "   fx: {:.17g}\n   fy: {:.17g}\n   cx: {:.17g}\n   cy: {:.17g}\n",
                                c.width, c.height, c.fx, c.fy, c.cx, c.cy));
  }
  const sensors::ImuCalibration& imu = *folder.imu();
  const fs::path config = dir / "calibration.yaml";
  test::writeFile(config,
                  fmt::format("%YAML:1.0\nimu: 1\nnum_of_cam: 2\ncam0_calib: \"cam0.yaml\"\n"
                              "cam1_calib: \"cam1.yaml\"\nbody_T_cam0: {}body_T_cam1: {}"
                              "acc_n: {:.17g}\ngyr_n: {:.17g}\nacc_w: {:.17g}\n"
                              "gyr_w: {:.17g}\n",
                              matrix(folder.camera0().T_b_c), matrix(folder.camera1()->T_b_c),
                              imu.accelerometer_noise_density, imu.gyroscope_noise_density,
                              imu.accelerometer_random_walk, imu.gyroscope_random_walk));
  return config;
}

TEST(BagSource, AVinsConfigFileCalibratesTheBagAsTheFoldersSensorYamlFiles) {
  const fs::path& sequence = streetSequence();
  const test::ScratchDir dir("bag_source_vins");
  const fs::path file = dir / "street.bag";
  writeViodeBag(sequence, file, "none");
  const auto folder = io::openDataset(io::DatasetKind::kEuroc, sequence, {});
  ASSERT_TRUE(std::all_of(folder->camera0().distortion.begin(), folder->camera0().distortion.end(),
                          [](double k) { return k == 0.0; }));  // as the file writes
  const auto bag =
      openBagSource(file, writeVinsConfig(dir.path(), *folder), bagTopicsPreset("viode"), {});
  for (const auto& [actual, expected] :
       {std::pair{&bag->camera0(), &folder->camera0()}, {&*bag->camera1(), &*folder->camera1()}}) {
    EXPECT_EQ(actual->fx, expected->fx);
    EXPECT_EQ(actual->cy, expected->cy);
    EXPECT_EQ(actual->width, expected->width);
    EXPECT_EQ(actual->distortion_model, expected->distortion_model);
    EXPECT_EQ(actual->distortion, expected->distortion);
    EXPECT_LT((actual->T_b_c.t - expected->T_b_c.t).norm(), 1e-12);
    EXPECT_LT(actual->T_b_c.q.angularDistance(expected->T_b_c.q), 1e-12);
    EXPECT_NEAR(actual->rate_hz, expected->rate_hz, 1e-6);  // measured from the stamps
  }
  EXPECT_EQ(bag->imu()->accelerometer_noise_density, folder->imu()->accelerometer_noise_density);
  EXPECT_EQ(bag->imu()->gyroscope_random_walk, folder->imu()->gyroscope_random_walk);
  EXPECT_NEAR(bag->imu()->rate_hz, folder->imu()->rate_hz, 1e-6);
}

TEST(BagSource, TopicFilesNameAnyTopicsAndTransformsServeAsGroundTruth) {
  const fs::path& sequence = streetSequence();
  const test::ScratchDir dir("bag_source_topic_file");
  const fs::path file = dir / "mocap.bag";
  const auto folder = io::openDataset(io::DatasetKind::kEuroc, sequence, {});
  {
    BagWriter out(file, "none");
    const cv::Mat image(folder->camera0().height, folder->camera0().width, CV_8UC1, cv::Scalar(90));
    for (const TimeNs t : {TimeNs{2000000000}, TimeNs{2050000000}})
      out.writeImage("/left", t, image, "cam0");
    sensors::GroundTruthState state;
    state.T_w_b = SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ())),
                       Eigen::Vector3d(1.0, 2.0, 3.0));
    for (const TimeNs t : {TimeNs{2000000000}, TimeNs{2050000000}}) {
      state.t_ns = t;
      out.writeTransform("/vrpn_client/raw_transform", state);
    }
    out.close();
  }
  test::writeFile(dir / "topics.yaml", "cam0: /left\nground_truth: /vrpn_client/raw_transform\n");
  io::DatasetSourceOptions mono;
  mono.stereo = false;
  mono.inertial = false;
  const auto bag = openBagSource(file, sequence, bagTopics((dir / "topics.yaml").string()), mono);
  ASSERT_EQ(bag->size(), 2u);
  ASSERT_EQ(bag->groundTruth().size(), 2u);
  EXPECT_LT((bag->groundTruth()[1].T_w_x.t - Eigen::Vector3d(1.0, 2.0, 3.0)).norm(), 1e-12);
  const auto frame = bag->next();
  ASSERT_TRUE(frame && frame->T_w_b_gt);
  EXPECT_NEAR(frame->T_w_b_gt->q.angularDistance(
                  Eigen::Quaterniond(Eigen::AngleAxisd(0.3, Eigen::Vector3d::UnitZ()))),
              0.0, 1e-12);

  test::writeFile(dir / "bad.yaml", "cam0: /left\nimu0: /imu\n");
  test::expectError([&] { readBagTopics(dir / "bad.yaml"); }, {"bad.yaml", "imu0", "unknown key"});
  test::writeFile(dir / "bad.yaml", "cam1: /right\n");
  test::expectError([&] { readBagTopics(dir / "bad.yaml"); }, {"bad.yaml", "cam0", "missing"});
  test::writeFile(dir / "bad.yaml", "cam0: /left\nimu: /imu\naccel: /accel\n");
  test::expectError([&] { readBagTopics(dir / "bad.yaml"); }, {"bad.yaml", "either imu or accel"});
  EXPECT_EQ(bagTopics("tumvi").ground_truth, "/vrpn_client/raw_transform");
}

TEST(BagSource, HeaderStampsOutOfTheBagsOrderAreAnError) {
  const fs::path& sequence = streetSequence();
  const test::ScratchDir dir("bag_source_order");
  const fs::path file = dir / "unordered.bag";
  {
    BagWriter out(file, "none");
    const cv::Mat image(480, 752, CV_8UC1, cv::Scalar(90));
    for (const TimeNs t : {TimeNs{2000000000}, TimeNs{2050000000}}) {
      out.writeImage("/cam0/image_raw", t, image, "cam0");
      out.writeImage("/cam1/image_raw", t, image, "cam1");
    }
    // Recorded in this order (record times 1, 2, 3 ms after the first) with stamps out of order.
    sensors::ImuSample sample;
    TimeNs recorded = 1990000000;
    for (const TimeNs t : {TimeNs{1990000000}, TimeNs{2060000000}, TimeNs{2010000000}}) {
      sample.t_ns = t;
      out.writeImu("/imu0", sample, "imu0", recorded += kNsPerMillisecond);
    }
    out.close();
  }
  test::expectError([&] { openBagSource(file, sequence, BagTopics{}, {}); },
                    {file.string(), "topic /imu0: message 1 is stamped 2060000000 ns",
                     "out of the recorded order"});
}

}  // namespace
}  // namespace superdyna::bag
