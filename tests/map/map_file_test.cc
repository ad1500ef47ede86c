#include "superdyna/map/map_file.h"

#include <gtest/gtest.h>

#include <algorithm>
#include <boost/crc.hpp>
#include <cstdint>
#include <filesystem>
#include <fstream>
#include <random>

#include "superdyna/core/error.h"

namespace superdyna::map {
namespace {

namespace fs = std::filesystem;

/// A small stereo-inertial-like map: 4 keyframes with IMU runs, binary descriptors, keypoints of
/// two classes, 30 points seen by 2-3 keyframes each, one keyframe erased (ids with a gap).
std::unique_ptr<Map> makeMap() {
  MapOptions options;
  options.T_b_c = {SE3d(), SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.11, 0, 0))};
  auto map = std::make_unique<Map>(options);
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> u(-1.0, 1.0);
  std::vector<KeyFrameId> keyframes;
  for (int k = 0; k < 5; ++k) {
    KeyFrame kf;
    kf.t_ns = 1'000'000'000LL + k * 250'000'000LL;
    kf.T_w_b = SE3d(Eigen::Quaterniond(Eigen::AngleAxisd(0.1 * k, Eigen::Vector3d::UnitZ())),
                    Eigen::Vector3d(0.3 * k, u(rng), 0.5));
    kf.v_w = Eigen::Vector3d(1.2, 0.1 * k, 0.0);
    kf.bg = Eigen::Vector3d(1e-3, -2e-3, 5e-4);
    kf.ba = Eigen::Vector3d(0.02, 0.01, -0.03);
    for (int s = 0; s < 3 && k > 0; ++s)
      kf.imu_from_previous.push_back({kf.t_ns - 250'000'000LL + s * 125'000'000LL,
                                      Eigen::Vector3d(u(rng), u(rng), u(rng)),
                                      Eigen::Vector3d(u(rng), u(rng), 9.81)});
    kf.keypoints.resize(40);
    for (std::size_t i = 0; i < kf.keypoints.size(); ++i) {
      KeyFrameKeypoint& kp = kf.keypoints[i];
      kp.pixel = Eigen::Vector2d(10.0 * i, 3.0 * k);
      kp.normalized = Eigen::Vector2d(u(rng), u(rng));
      kp.octave = static_cast<int>(i % 4);
      kp.angle = static_cast<float>(i);
      kp.class_id = i % 7 == 0 ? 1 : 0;
      kp.instance_id = i % 7 == 0 ? 3 : 0;
      kp.depth_m = i % 2 == 0 ? 4.0 + u(rng) : -1.0;
      kp.right_x = kp.normalized.x() - 0.02;
    }
    kf.descriptors = cv::Mat(40, 32, CV_8UC1);
    cv::randu(kf.descriptors, 0, 256);
    keyframes.push_back(map->addKeyFrame(std::move(kf)));
  }
  for (int i = 0; i < 30; ++i) {
    MapPoint p;
    p.p_w = Eigen::Vector3d(u(rng), u(rng), 5.0 + u(rng));
    p.descriptor = cv::Mat(1, 32, CV_8UC1, cv::Scalar(i));
    p.class_id = i % 7 == 0 ? 1 : 0;
    const MapPointId id = map->addMapPoint(std::move(p));
    for (int k = i % 3; k < 5; k += 2)
      EXPECT_TRUE(map->addObservation(id, keyframes[static_cast<std::size_t>(k)], i));
    map->updateNormalAndDistances(id);
  }
  map->eraseKeyFrame(keyframes[2]);
  map->eraseBadMapPoints();
  return map;
}

MapIdentity orbStereoInertial() {
  MapIdentity identity;
  identity.feature_type = "orb";
  identity.descriptor_type = MapDescriptorType::kBinary;
  identity.descriptor_columns = 32;
  identity.sensor_mode = "stereo-inertial";
  sensors::CameraCalibration cam;
  cam.name = "cam0";
  cam.width = 752;
  cam.height = 480;
  cam.fx = 458.654;
  cam.fy = 457.296;
  cam.cx = 367.215;
  cam.cy = 248.375;
  identity.cameras = {cam, cam};
  identity.cameras[1].name = "cam1";
  identity.cameras[1].T_b_c.t = Eigen::Vector3d(0.11, 0, 0);
  identity.T_b_i = SE3d();
  return identity;
}

std::map<KeyFrameId, RightKeypoints> rightOf(const Map& map) {
  std::map<KeyFrameId, RightKeypoints> right;
  for (const KeyFrameId id : map.keyFrameIds()) {
    RightKeypoints r(map.keyFrame(id)->size());
    for (std::size_t i = 0; i < r.size(); i += 2)
      r[i] = Eigen::Vector2d(0.01 * static_cast<double>(i), -0.2);
    right.emplace(id, r);
  }
  return right;
}

std::string savedBytes() {
  const std::unique_ptr<Map> map = makeMap();
  return serializeMapFile(makeMapFile(*map, orbStereoInertial(), rightOf(*map), 2));
}

/// The message of the InputError parsing `bytes` throws ("" when none).
std::string parseError(const std::string& bytes) {
  try {
    parseMapFile(bytes, "damaged.sdmap");
  } catch (const InputError& e) {
    return e.what();
  }
  return "";
}

TEST(MapFile, RoundTripGivesTheSameMapAndIdenticalBytes) {
  const std::unique_ptr<Map> map = makeMap();
  const std::string first =
      serializeMapFile(makeMapFile(*map, orbStereoInertial(), rightOf(*map), 2));
  const MapFile loaded = parseMapFile(first, "first.sdmap");
  const std::unique_ptr<Map> rebuilt = buildMap(loaded);
  EXPECT_EQ(rebuilt->consistencyError(), "");
  ASSERT_EQ(rebuilt->keyFrameIds(), map->keyFrameIds());
  EXPECT_EQ(rebuilt->mapPointIds(), map->mapPointIds());
  EXPECT_EQ(rebuilt->newestKeyFrame(), map->newestKeyFrame());
  for (const KeyFrameId id : map->keyFrameIds()) {
    EXPECT_EQ(rebuilt->covisibleKeyFrames(id), map->covisibleKeyFrames(id));
    const KeyFrame a = *map->keyFrame(id), b = *rebuilt->keyFrame(id);
    EXPECT_EQ(a.previous, b.previous);
    EXPECT_EQ(a.map_points, b.map_points);
    EXPECT_EQ(a.imu_from_previous.size(), b.imu_from_previous.size());
    EXPECT_EQ(cv::norm(a.descriptors, b.descriptors, cv::NORM_HAMMING), 0.0);
    EXPECT_EQ(a.T_w_b.t, b.T_w_b.t);
    EXPECT_EQ(a.v_w, b.v_w);
    EXPECT_EQ(a.ba, b.ba);
  }
  EXPECT_EQ(loaded.inertial_stages, 2);
  EXPECT_EQ(loaded.identity.cameras[1].T_b_c.t.x(), 0.11);
  EXPECT_EQ(loaded.right.size(), map->numKeyFrames());
  // A new keyframe of the loaded map gets the id the saved map would have given it.
  EXPECT_EQ(rebuilt->addKeyFrame(KeyFrame{}), map->addKeyFrame(KeyFrame{}));

  const MapFile reloaded = parseMapFile(first, "first.sdmap");
  const std::string second = serializeMapFile(makeMapFile(
      *buildMap(reloaded), reloaded.identity, reloaded.right, reloaded.inertial_stages));
  EXPECT_EQ(second, first);
}

TEST(MapFile, WritesAtomicallyAndReadsBack) {
  const fs::path dir = fs::temp_directory_path() / "superdyna_map_file_test";
  fs::create_directories(dir);
  const fs::path path = dir / "map.sdmap";
  const std::unique_ptr<Map> map = makeMap();
  writeMapFile(path, makeMapFile(*map, orbStereoInertial(), rightOf(*map), 1));
  EXPECT_EQ(readMapFile(path).contents.points.size(), map->numMapPoints());
  EXPECT_EQ(std::distance(fs::directory_iterator(dir), fs::directory_iterator()), 1);  // no tmp
  fs::remove_all(dir);
  EXPECT_THROW(readMapFile(dir / "missing.sdmap"), InputError);
}

TEST(MapFile, TruncatedFilesNameTheTruncation) {
  const std::string bytes = savedBytes();
  EXPECT_NE(parseError(bytes.substr(0, 10)).find("truncated: 10 bytes"), std::string::npos);
  const std::string cut = parseError(bytes.substr(0, bytes.size() - 100));
  EXPECT_NE(cut.find("damaged.sdmap"), std::string::npos) << cut;
  EXPECT_NE(cut.find("truncated: the header announces"), std::string::npos) << cut;
  EXPECT_NE(parseError("").find("truncated: 0 bytes"), std::string::npos);
}

TEST(MapFile, CorruptedPayloadFailsTheChecksum) {
  std::string bytes = savedBytes();
  bytes[bytes.size() / 2] = static_cast<char>(bytes[bytes.size() / 2] ^ 0x10);
  EXPECT_NE(parseError(bytes).find("corrupted: the payload's CRC-32"), std::string::npos);
  std::string longer = savedBytes() + "x";
  EXPECT_NE(parseError(longer).find("corrupted: the header announces"), std::string::npos);
}

TEST(MapFile, WrongMagicAndVersionAreNamed) {
  std::string bytes = savedBytes();
  bytes[0] = 'X';
  EXPECT_NE(parseError(bytes).find("not a SuperDynaSLAM map file"), std::string::npos);
  bytes = savedBytes();
  bytes[9] = 7;  // version, little-endian, after the magic and cereal's endianness byte
  const std::string error = parseError(bytes);
  EXPECT_NE(error.find("format version 7; this build reads version 1"), std::string::npos) << error;
}

TEST(MapFile, InconsistentContentsAreRejectedEvenWithAValidChecksum) {
  const std::unique_ptr<Map> map = makeMap();
  MapFile file = makeMapFile(*map, orbStereoInertial(), rightOf(*map), 2);
  file.contents.points.front().observations.begin()->second = 39;  // another keypoint
  EXPECT_NE(parseError(serializeMapFile(file)).find("inconsistent map"), std::string::npos);
  file = makeMapFile(*map, orbStereoInertial(), rightOf(*map), 2);
  std::get<2>(file.covisibility.front()) += 1;
  EXPECT_NE(parseError(serializeMapFile(file)).find("covisibility"), std::string::npos);
  file = makeMapFile(*map, orbStereoInertial(), rightOf(*map), 2);
  file.identity.descriptor_type = MapDescriptorType::kFloat;
  EXPECT_NE(parseError(serializeMapFile(file)).find("descriptors of type 0 with 32 columns"),
            std::string::npos);
}

TEST(MapFile, FuzzedFilesNeverCrash) {
  const std::string bytes = savedBytes();
  std::mt19937 rng(11);
  int rejected = 0;
  for (int trial = 0; trial < 300; ++trial) {
    std::string damaged = bytes;
    const int flips = 1 + trial % 5;
    for (int f = 0; f < flips; ++f) {
      const std::size_t at = rng() % damaged.size();
      damaged[at] = static_cast<char>(rng());
    }
    if (trial % 3 == 0) damaged.resize(rng() % damaged.size());
    if (!parseError(damaged).empty()) ++rejected;
  }
  EXPECT_GE(rejected, 295);  // a flip may rewrite a byte with its own value
}

/// `bytes` with another payload, under a header whose size and CRC-32 match it (the layout of
/// map_file.h: magic, endianness, version, descriptor type, size at byte 14, CRC at byte 22).
std::string withValidHeader(const std::string& bytes, const std::string& payload) {
  constexpr std::size_t kHeaderBytes = 26;
  std::string file = bytes.substr(0, kHeaderBytes) + payload;
  boost::crc_32_type crc;
  crc.process_bytes(payload.data(), payload.size());
  const auto put = [&](std::size_t at, std::uint64_t value, int count) {
    for (int i = 0; i < count; ++i)
      file[at + static_cast<std::size_t>(i)] = static_cast<char>((value >> (8 * i)) & 0xFF);
  };
  put(14, payload.size(), 8);
  put(22, crc.checksum(), 4);
  return file;
}

TEST(MapFile, HugeStoredLengthsFailAtTheEndOfThePayloadWithoutAllocatingThem) {
  // Found by fuzzing (fuzz/map_file_fuzzer.cc): with a valid checksum, a stored length was
  // allocated before reading (here 1 TiB characters: std::bad_alloc; lengths that fit in memory
  // were allocated and zero-filled); now the load reads as far as the payload goes.
  const std::string bytes = savedBytes();
  ASSERT_EQ(parseError(withValidHeader(bytes, bytes.substr(26))), "");
  std::string payload = bytes.substr(26);
  // The payload's cereal archive starts with its endianness byte, then the length of the first
  // string (the feature type, "orb").
  const std::uint64_t length = std::uint64_t{1} << 40;
  for (int i = 0; i < 8; ++i)
    payload[static_cast<std::size_t>(1 + i)] = static_cast<char>((length >> (8 * i)) & 0xFF);
  const std::string error = parseError(withValidHeader(bytes, payload));
  EXPECT_NE(error.find("corrupted payload: Failed to read"), std::string::npos) << error;
}

TEST(MapFile, BooleansOtherThanZeroOrOneAreRejected) {
  // Found by fuzzing (fuzz/map_file_fuzzer.cc): the byte of a boolean (here: whether the IMU pose
  // is stored) was copied into a bool whatever its value (undefined behaviour).
  const std::unique_ptr<Map> map = makeMap();
  MapFile file = makeMapFile(*map, orbStereoInertial(), rightOf(*map), 2);
  const std::string with_imu = serializeMapFile(file);
  file.identity.T_b_i.reset();
  const std::string without_imu = serializeMapFile(file);
  const auto flag = std::mismatch(with_imu.begin() + 26, with_imu.end(), without_imu.begin() + 26);
  ASSERT_NE(flag.first, with_imu.end());
  std::string payload = with_imu.substr(26);
  payload[static_cast<std::size_t>(flag.first - with_imu.begin()) - 26] = 64;
  const std::string error = parseError(withValidHeader(with_imu, payload));
  EXPECT_NE(error.find("boolean stored as byte 64"), std::string::npos) << error;
}

TEST(MapFile, IdentityMismatchNamesWhatDiffers) {
  const MapIdentity saved = orbStereoInertial();
  EXPECT_EQ(identityMismatch(saved, saved), "");
  MapIdentity other = saved;
  other.feature_type = "xfeat";
  EXPECT_NE(identityMismatch(saved, other).find("made with orb features, this run uses xfeat"),
            std::string::npos);
  other = saved;
  other.cameras[0].fx = 400.0;
  EXPECT_EQ(identityMismatch(saved, other),
            "camera 0 differs in fx: the map's 458.654, this run's 400");
  other = saved;
  other.cameras[1].height = 512;
  EXPECT_EQ(identityMismatch(saved, other),
            "camera 1 differs in resolution: the map's 752x480, this run's 752x512");
  other = saved;
  other.cameras[0].distortion_model = DistortionModel::kRadialTangential;
  other.cameras[0].distortion = {-0.28, 0.07, 0.0002, 1.8e-05};
  EXPECT_EQ(identityMismatch(saved, other),
            "camera 0 differs in distortion model: the map's none, this run's radial-tangential");
  MapIdentity distorted = other;
  other.cameras[0].distortion[2] = 0.0003;
  EXPECT_EQ(identityMismatch(distorted, other),
            "camera 0 differs in distortion p1: the map's 0.0002, this run's 0.0003");
  other = saved;
  other.cameras[1].T_b_c.t.x() = 0.12;
  EXPECT_EQ(identityMismatch(saved, other),
            "camera 1 differs in pose in the body (T_b_c) translation: the map's (0.11, 0, 0) m, "
            "this run's (0.12, 0, 0) m");
  other = saved;
  other.cameras[0].T_b_c = SE3d(expSO3(Eigen::Vector3d(0, 0, 0.01)), Eigen::Vector3d::Zero());
  EXPECT_EQ(identityMismatch(saved, other),
            "camera 0 differs in pose in the body (T_b_c) rotation: this run's is turned 0.572958 "
            "deg from the map's");
  other = saved;
  other.T_b_i->t.z() = 0.05;
  EXPECT_EQ(identityMismatch(saved, other),
            "the IMU differs in pose in the body (T_b_i) translation: the map's (0, 0, 0) m, this "
            "run's (0, 0, 0.05) m");
  other = saved;
  other.sensor_mode = "stereo";
  EXPECT_NE(identityMismatch(saved, other).find("stereo-inertial mode"), std::string::npos);
}

}  // namespace
}  // namespace superdyna::map
