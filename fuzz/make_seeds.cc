// Writes the binary seeds of the fuzz corpora (fuzz/corpus/): a small valid map file (raw, and
// as a payload for the valid-header mode of map_file_fuzzer) and PNG images for the mask and
// segmentation targets. Text seeds are written by hand. Usage: superdyna_fuzz_make_seeds CORPUS
// (the fuzz/corpus folder). Built with SUPERDYNA_FUZZ=ON only; run once when the formats change.

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <opencv2/imgcodecs.hpp>
#include <string>
#include <vector>

#include "superdyna/map/map_file.h"

namespace {

namespace fs = std::filesystem;
using namespace superdyna;

void writeSeed(const fs::path& file, char selector, const std::string& bytes) {
  fs::create_directories(file.parent_path());
  std::ofstream out(file, std::ios::binary);
  out << selector << bytes;
}

std::string png(const cv::Mat& image) {
  std::vector<std::uint8_t> bytes;
  cv::imencode(".png", image, bytes);
  return {bytes.begin(), bytes.end()};
}

/// Two keyframes with six keypoints each and three points seen by both.
std::unique_ptr<map::Map> smallMap() {
  map::MapOptions options;
  options.T_b_c = {SE3d(), SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.11, 0, 0))};
  auto m = std::make_unique<map::Map>(options);
  std::vector<map::KeyFrameId> keyframes;
  for (int k = 0; k < 2; ++k) {
    map::KeyFrame kf;
    kf.t_ns = 1'000'000'000LL + k * 250'000'000LL;
    kf.T_w_b = SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(0.3 * k, 0.0, 0.0));
    if (k > 0)
      kf.imu_from_previous.push_back(
          {kf.t_ns - 125'000'000LL, Eigen::Vector3d(0, 0, 0.1), Eigen::Vector3d(0, 0, 9.81)});
    kf.keypoints.resize(6);
    for (std::size_t i = 0; i < kf.keypoints.size(); ++i) {
      map::KeyFrameKeypoint& kp = kf.keypoints[i];
      kp.pixel = Eigen::Vector2d(10.0 * static_cast<double>(i), 3.0 * k);
      kp.normalized = Eigen::Vector2d(0.01 * static_cast<double>(i), 0.02 * k);
      kp.class_id = i == 0 ? 1 : 0;
      kp.instance_id = i == 0 ? 3 : 0;
      kp.depth_m = i % 2 == 0 ? 4.0 : -1.0;
      kp.right_x = kp.normalized.x() - 0.02;
    }
    kf.descriptors = cv::Mat(6, 32, CV_8UC1, cv::Scalar(17 * k));
    keyframes.push_back(m->addKeyFrame(std::move(kf)));
  }
  for (int i = 0; i < 3; ++i) {
    map::MapPoint p;
    p.p_w = Eigen::Vector3d(0.1 * i, 0.0, 5.0);
    p.descriptor = cv::Mat(1, 32, CV_8UC1, cv::Scalar(i));
    const map::MapPointId id = m->addMapPoint(std::move(p));
    for (const map::KeyFrameId kf : keyframes)
      m->addObservation(id, kf, i);
    m->updateNormalAndDistances(id);
  }
  return m;
}

map::MapIdentity stereoInertialOrb() {
  map::MapIdentity identity;
  identity.feature_type = "orb";
  identity.descriptor_type = map::MapDescriptorType::kBinary;
  identity.descriptor_columns = 32;
  identity.sensor_mode = "stereo-inertial";
  sensors::CameraCalibration camera;
  camera.name = "cam0";
  camera.width = 8;
  camera.height = 6;
  camera.fx = camera.fy = 4.0;
  camera.cx = 4.0;
  camera.cy = 3.0;
  identity.cameras = {camera, camera};
  identity.cameras[1].name = "cam1";
  identity.cameras[1].T_b_c.t = Eigen::Vector3d(0.11, 0, 0);
  identity.T_b_i = SE3d();
  return identity;
}

void writeMapSeeds(const fs::path& corpus) {
  const std::unique_ptr<map::Map> m = smallMap();
  std::map<map::KeyFrameId, map::RightKeypoints> right;
  for (const map::KeyFrameId id : m->keyFrameIds())
    right.emplace(id, map::RightKeypoints(m->keyFrame(id)->size(), Eigen::Vector2d(1.0, 2.0)));
  const std::string bytes =
      map::serializeMapFile(map::makeMapFile(*m, stereoInertialOrb(), right, 1));
  (void)map::parseMapFile(bytes, "seed");  // throws unless the seed is a valid map file
  constexpr std::size_t kHeaderBytes = 26;
  writeSeed(corpus / "map_file" / "small_map", 0, bytes);
  writeSeed(corpus / "map_file" / "small_map_payload", 1 + 2 * 1, bytes.substr(kHeaderBytes));
}

void writeImageSeeds(const fs::path& corpus) {
  cv::Mat ids(6, 8, CV_16UC1, cv::Scalar(0));
  ids(cv::Rect(2, 1, 3, 3)).setTo(1);
  ids(cv::Rect(6, 4, 2, 2)).setTo(2);
  writeSeed(corpus / "instance_mask" / "mask_png", 0, png(ids));
  cv::Mat colours(6, 8, CV_8UC3, cv::Scalar(0, 0, 0));
  colours(cv::Rect(1, 1, 3, 2)).setTo(cv::Scalar(0, 0, 255));
  colours(cv::Rect(5, 3, 2, 2)).setTo(cv::Scalar(255, 0, 0));
  writeSeed(corpus / "segmentation" / "colour_png", 2, png(colours));
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::cerr << "usage: " << argv[0] << " CORPUS_DIR\n";
    return 2;
  }
  writeMapSeeds(argv[1]);
  writeImageSeeds(argv[1]);
  return 0;
}
