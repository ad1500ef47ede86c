#include "superdyna/bag/sequence_bag_writer.h"

#include <cmath>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <utility>
#include <vector>

#include "superdyna/bag/bag_writer.h"
#include "superdyna/core/error.h"
#include "superdyna/io/calibration.h"
#include "superdyna/io/euroc_dataset.h"
#include "superdyna/sensors/imu_streams.h"

namespace superdyna::bag {

namespace fs = std::filesystem;

namespace {

/// Writes one camera's images, and its segmentation images when the folder has them.
void writeCamera(BagWriter& out, const fs::path& camera_dir, const std::string& camera,
                 const std::vector<std::pair<TimeNs, fs::path>>& frames) {
  const fs::path segmentation = camera_dir / "segmentation";
  const bool with_segmentation = fs::is_directory(segmentation);
  for (const auto& [t_ns, file] : frames) {
    out.writeImage("/" + camera + "/image_raw", t_ns, io::decodePngFile(file, cv::IMREAD_GRAYSCALE),
                   camera);
    if (!with_segmentation) continue;
    out.writeImage("/" + camera + "/segmentation", t_ns,
                   io::decodePngFile(segmentation / file.filename(), cv::IMREAD_COLOR), camera);
  }
}

/// The left camera's frames of the dataset (of each stereo pair, or the mono frames).
std::vector<std::pair<TimeNs, fs::path>> leftFrames(const io::EurocDataset& dataset) {
  std::vector<std::pair<TimeNs, fs::path>> left;
  if (dataset.isStereo()) {
    for (const io::StereoFrameRef& frame : dataset.stereoFrames())
      left.emplace_back(frame.t_ns, frame.cam0);
  } else {
    for (const io::ImageRef& frame : dataset.monoFrames())
      left.emplace_back(frame.t_ns, frame.path);
  }
  return left;
}

/// The IMU's acceleration resampled at kOpenlorisAccelRateHz, 2 ms after its first sample on.
std::vector<sensors::ImuSample> resampledAccel(const std::vector<sensors::ImuSample>& imu) {
  const auto period_ns = static_cast<TimeNs>(std::llround(1e9 / kOpenlorisAccelRateHz));
  std::vector<sensors::ImuSample> stamps;  // the output times, as a "gyroscope" stream to merge
  for (TimeNs t = imu.front().t_ns + 2 * kNsPerMillisecond; t <= imu.back().t_ns; t += period_ns)
    stamps.push_back({.t_ns = t});
  std::vector<sensors::ImuSample> accel = sensors::mergeImuStreams(imu, stamps).samples;
  for (sensors::ImuSample& sample : accel)
    sample.gyro.setZero();
  return accel;
}

}  // namespace

std::map<std::string, std::size_t> writeViodeBag(const fs::path& sequence, const fs::path& bag,
                                                 const std::string& compression) {
  const io::EurocDataset dataset = io::EurocDataset::open(sequence);
  const std::vector<std::pair<TimeNs, fs::path>> left = leftFrames(dataset);
  std::vector<std::pair<TimeNs, fs::path>> right;
  if (dataset.isStereo()) {
    for (const io::StereoFrameRef& frame : dataset.stereoFrames())
      right.emplace_back(frame.t_ns, frame.cam1);
  }
  BagWriter out(bag, compression);
  writeCamera(out, dataset.root() / "cam0", "cam0", left);
  if (!right.empty()) writeCamera(out, dataset.root() / "cam1", "cam1", right);
  for (const sensors::ImuSample& sample : dataset.imu())
    out.writeImu("/imu0", sample, "imu0");
  for (const sensors::GroundTruthState& state : dataset.groundTruth())
    out.writeOdometry("/odometry", state);
  out.close();
  return out.counts();
}

std::map<std::string, std::size_t> writeOpenlorisBag(const fs::path& sequence, const fs::path& bag,
                                                     const std::string& compression) {
  const io::EurocDataset dataset = io::EurocDataset::open(sequence);
  if (dataset.imu().size() < 2) {
    throw InputError(InputLocation{dataset.root() / "imu0" / "data.csv"},
                     "an OpenLORIS-layout bag needs the IMU (at least two samples)");
  }
  BagWriter out(bag, compression);
  for (const auto& [t_ns, file] : leftFrames(dataset)) {
    cv::Mat rgb;
    cv::cvtColor(io::decodePngFile(file, cv::IMREAD_GRAYSCALE), rgb, cv::COLOR_GRAY2BGR);
    out.writeImage("/d400/color/image_raw", t_ns, rgb, "d400_color_optical_frame",
                   ColourOrder::kRgb);
  }
  for (const sensors::ImuSample& sample : dataset.imu()) {
    out.writeImu("/d400/gyro/sample",
                 {.t_ns = sample.t_ns, .gyro = sample.gyro, .accel = Eigen::Vector3d::Zero()},
                 "d400_imu_optical_frame");
  }
  for (const sensors::ImuSample& sample : resampledAccel(dataset.imu()))
    out.writeImu("/d400/accel/sample", sample, "d400_imu_optical_frame");
  out.close();
  return out.counts();
}

}  // namespace superdyna::bag
