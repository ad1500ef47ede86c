#include "superdyna/bag/sequence_bag_writer.h"

#include <opencv2/imgcodecs.hpp>
#include <utility>
#include <vector>

#include "superdyna/bag/bag_writer.h"
#include "superdyna/io/calibration.h"
#include "superdyna/io/euroc_dataset.h"

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

}  // namespace

std::map<std::string, std::size_t> writeViodeBag(const fs::path& sequence, const fs::path& bag,
                                                 const std::string& compression) {
  const io::EurocDataset dataset = io::EurocDataset::open(sequence);
  std::vector<std::pair<TimeNs, fs::path>> left, right;
  if (dataset.isStereo()) {
    for (const io::StereoFrameRef& frame : dataset.stereoFrames()) {
      left.emplace_back(frame.t_ns, frame.cam0);
      right.emplace_back(frame.t_ns, frame.cam1);
    }
  } else {
    for (const io::ImageRef& frame : dataset.monoFrames())
      left.emplace_back(frame.t_ns, frame.path);
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

}  // namespace superdyna::bag
