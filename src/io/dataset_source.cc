#include "superdyna/io/dataset_source.h"

#include <fmt/format.h>

#include <algorithm>

#include "superdyna/core/error.h"
#include "superdyna/io/kitti_dataset.h"

namespace superdyna::io {

namespace fs = std::filesystem;

namespace {

constexpr TimeNs kGroundTruthToleranceNs = kNsPerMillisecond;

/// The frames to serve after skipping and truncation, as stereo references (cam1 empty in mono).
std::vector<StereoFrameRef> selectFrames(std::vector<StereoFrameRef> frames,
                                         const DatasetSourceOptions& options,
                                         const fs::path& root) {
  if (options.first_frame >= frames.size()) {
    throw OptionError("first-frame",
                      fmt::format("{} has only {} usable frames, cannot skip {}", root.string(),
                                  frames.size(), options.first_frame));
  }
  frames.erase(frames.begin(), frames.begin() + static_cast<std::ptrdiff_t>(options.first_frame));
  if (options.max_frames > 0 && frames.size() > options.max_frames)
    frames.resize(options.max_frames);
  return frames;
}

std::vector<StereoFrameRef> asStereoRefs(const std::vector<ImageRef>& mono) {
  std::vector<StereoFrameRef> frames;
  frames.reserve(mono.size());
  for (const ImageRef& image : mono)
    frames.push_back({image.t_ns, image.path, {}});
  return frames;
}

/// A source serving a fixed list of frames; the dataset-specific part adds IMU and ground truth.
class FrameListSource : public DatasetSource {
 public:
  std::optional<sensors::FrameBundle> next() override {
    if (next_ >= frames_.size()) return std::nullopt;
    const StereoFrameRef& ref = frames_[next_];
    sensors::FrameBundle bundle;
    bundle.index = next_;
    bundle.t_ns = ref.t_ns;
    bundle.image0 = loadImage(ref.cam0, camera0());
    if (options_.stereo) bundle.image1 = loadImage(ref.cam1, *camera1_);
    addMeasurements(next_, &bundle);
    ++next_;
    return bundle;
  }

  std::size_t size() const override { return frames_.size(); }
  const std::optional<sensors::CameraCalibration>& camera1() const override { return camera1_; }

 protected:
  explicit FrameListSource(const DatasetSourceOptions& options) : options_(options) {}

  /// Adds the IMU samples and ground truth of frame `index` to its bundle.
  virtual void addMeasurements(std::size_t index, sensors::FrameBundle* bundle) const = 0;

  DatasetSourceOptions options_;
  std::optional<sensors::CameraCalibration> camera1_;
  std::vector<StereoFrameRef> frames_;

 private:
  std::size_t next_ = 0;
};

class EurocSource : public FrameListSource {
 public:
  EurocSource(const fs::path& path, const DatasetSourceOptions& options)
      : FrameListSource(options), dataset_(EurocDataset::open(path)) {
    if (options.stereo && !dataset_.isStereo()) {
      throw InputError(InputLocation(dataset_.root() / "cam1"),
                       "stereo requested but the dataset has no cam1 (use a mono mode)");
    }
    if (options.inertial && !dataset_.hasImu()) {
      throw InputError(InputLocation(dataset_.root() / "imu0"),
                       "inertial mode requested but the dataset has no imu0");
    }
    if (options.instance_masks && !dataset_.hasInstanceMasks()) {
      throw InputError(InputLocation(dataset_.root() / "instances.csv"),
                       "instance masks requested but the dataset has no instances.csv and "
                       "cam0/mask/ (only simulated sequences have them)");
    }
    if (options.stereo) camera1_ = dataset_.cam1Calibration();
    if (options.inertial) imu_ = dataset_.imuCalibration();
    frames_ = selectFrames(availableFrames(), options, dataset_.root());
  }

  const sensors::CameraCalibration& camera0() const override { return dataset_.cam0Calibration(); }
  const std::optional<sensors::ImuCalibration>& imu() const override { return imu_; }
  const std::vector<std::string>& warnings() const override { return dataset_.warnings(); }

  Trajectory groundTruth() const override {
    Trajectory served;
    const TimeRange range{frames_.front().t_ns, frames_.back().t_ns};
    for (const StampedPose& pose : dataset_.groundTruthTrajectory()) {
      if (pose.t_ns + kGroundTruthToleranceNs >= range.begin &&
          pose.t_ns <= range.end + kGroundTruthToleranceNs) {
        served.push_back(pose);
      }
    }
    return served;
  }

 private:
  void addMeasurements(std::size_t index, sensors::FrameBundle* bundle) const override {
    if (options_.inertial) {
      const TimeNs t_prev = index == 0 ? bundle->t_ns : frames_[index - 1].t_ns;
      bundle->imu = bracketingImu(dataset_.imu(), t_prev, bundle->t_ns);
    }
    if (const auto gt = dataset_.groundTruthNearest(bundle->t_ns, kGroundTruthToleranceNs)) {
      bundle->T_w_b_gt = gt->T_w_b;
    }
    if (options_.instance_masks) addMasks(frames_[index], bundle);
  }

  void addMasks(const StereoFrameRef& frame, sensors::FrameBundle* bundle) const {
    sensors::InstanceMasks masks;
    masks.cam0 = dataset_.loadInstanceMask(frame.cam0, bundle->image0.size());
    if (!bundle->image1.empty()) {
      masks.cam1 = dataset_.loadInstanceMask(frame.cam1, bundle->image1.size());
    }
    masks.class_of_instance = dataset_.instanceClasses();
    bundle->masks = std::move(masks);
  }

  std::vector<StereoFrameRef> availableFrames() const {
    if (options_.stereo) {
      return options_.inertial ? dataset_.framesWithImuCoverage() : dataset_.stereoFrames();
    }
    return asStereoRefs(options_.inertial ? dataset_.monoFramesWithImuCoverage()
                                          : dataset_.monoFrames());
  }

  EurocDataset dataset_;
  std::optional<sensors::ImuCalibration> imu_;
};

class KittiSource : public FrameListSource {
 public:
  KittiSource(const fs::path& path, const DatasetSourceOptions& options)
      : FrameListSource(options), dataset_(KittiDataset::open(path)) {
    if (options.inertial) {
      throw InputError(InputLocation(path), "KITTI odometry has no IMU: use stereo or mono mode");
    }
    if (options.instance_masks) {
      throw InputError(InputLocation(path), "KITTI odometry has no instance masks");
    }
    if (options.stereo && !dataset_.isStereo()) {
      throw InputError(InputLocation(path),
                       "stereo requested but the sequence has no right images (use mono)");
    }
    if (options.stereo) camera1_ = dataset_.rightCalibration();
    frames_ =
        selectFrames(options.stereo ? dataset_.stereoFrames() : asStereoRefs(dataset_.monoFrames()),
                     options, dataset_.root());
  }

  const sensors::CameraCalibration& camera0() const override { return dataset_.leftCalibration(); }
  const std::optional<sensors::ImuCalibration>& imu() const override { return no_imu_; }
  const std::vector<std::string>& warnings() const override { return dataset_.warnings(); }

  Trajectory groundTruth() const override {
    Trajectory served;
    for (const StereoFrameRef& frame : frames_) {
      if (const auto pose = groundTruthAt(frame.t_ns)) served.push_back({frame.t_ns, *pose});
    }
    return served;
  }

 private:
  void addMeasurements(std::size_t /*index*/, sensors::FrameBundle* bundle) const override {
    bundle->T_w_b_gt = groundTruthAt(bundle->t_ns);
  }

  std::optional<SE3d> groundTruthAt(TimeNs t_ns) const {
    const Trajectory& gt = dataset_.groundTruth();
    const auto it = std::lower_bound(gt.begin(), gt.end(), t_ns,
                                     [](const StampedPose& p, TimeNs t) { return p.t_ns < t; });
    if (it == gt.end() || it->t_ns != t_ns) return std::nullopt;
    return it->T_w_x;
  }

  KittiDataset dataset_;
  std::optional<sensors::ImuCalibration> no_imu_;
};

}  // namespace

std::vector<sensors::ImuSample> bracketingImu(const std::vector<sensors::ImuSample>& imu, TimeNs t0,
                                              TimeNs t1) {
  const auto by_time = [](const sensors::ImuSample& s, TimeNs t) { return s.t_ns < t; };
  auto first = std::lower_bound(imu.begin(), imu.end(), t0, by_time);
  if (first != imu.begin() && (first == imu.end() || first->t_ns > t0)) --first;
  auto last = std::lower_bound(imu.begin(), imu.end(), t1, by_time);
  if (last != imu.end()) ++last;
  return {first, last};
}

DatasetKind parseDatasetKind(const std::string& name) {
  if (name == "euroc") return DatasetKind::kEuroc;
  if (name == "kitti") return DatasetKind::kKitti;
  throw OptionError("dataset", fmt::format("unknown dataset kind '{}' (euroc|kitti)", name));
}

std::unique_ptr<DatasetSource> openDataset(DatasetKind kind, const fs::path& path,
                                           const DatasetSourceOptions& options) {
  if (kind == DatasetKind::kKitti) return std::make_unique<KittiSource>(path, options);
  return std::make_unique<EurocSource>(path, options);
}

}  // namespace superdyna::io
