#include "superdyna/bag/bag_source.h"

#include <fmt/format.h>

#include <algorithm>
#include <optional>

#include "superdyna/bag/rosbag_reader.h"
#include "superdyna/core/error.h"
#include "superdyna/io/calibration.h"
#include "superdyna/io/trajectory_io.h"
#include "superdyna/io/vins_calibration.h"
#include "superdyna/io/yaml_file.h"
#include "superdyna/sensors/imu_streams.h"

namespace superdyna::bag {

namespace fs = std::filesystem;

namespace {

constexpr TimeNs kGroundTruthToleranceNs = kNsPerMillisecond;

/// The source reads each topic in the bag's order: header stamps out of that order are an error
/// rather than frames silently dropped or IMU intervals cut wrongly.
template <typename T, typename Stamp>
void requireStampOrder(const std::vector<T>& items, Stamp stamp, const fs::path& bag,
                       const std::string& topic) {
  const auto later = std::adjacent_find(
      items.begin(), items.end(), [&](const T& a, const T& b) { return stamp(b) < stamp(a); });
  if (later != items.end()) {
    throw InputError(
        InputLocation{bag},
        fmt::format("topic {}: message {} is stamped {} ns, after the next one ({} ns); "
                    "bags whose header stamps are out of the recorded order are not "
                    "supported",
                    topic, later - items.begin(), stamp(*later), stamp(*(later + 1))));
  }
}

bool hasTopic(const RosbagReader& reader, const std::string& name) {
  return std::any_of(reader.topics().begin(), reader.topics().end(),
                     [&](const BagTopic& topic) { return topic.name == name; });
}

class BagSource : public io::DatasetSource {
 public:
  BagSource(const fs::path& bag, const fs::path& calibration, const BagTopics& topics,
            const io::DatasetSourceOptions& options, const fs::path& ground_truth_file)
      : reader_(RosbagReader::open(bag)), topics_(topics), options_(options) {
    if (options.instance_masks) {
      throw InputError(InputLocation{bag}, "instance masks are not read from bags yet");
    }
    if (options.stereo && topics.cam1.empty()) {
      throw OptionError("--topics", "the topics name no second camera: run a mono mode");
    }
    if (options.inertial) readImu();
    readGroundTruth(ground_truth_file);
    selectFrames();
    io::SensorRig rig =
        io::readRigCalibration(calibration, options.stereo, options.inertial, measuredRates());
    camera0_ = std::move(rig.camera0);
    camera1_ = std::move(rig.camera1);
    imu_ = std::move(rig.imu);
    left_ = std::make_unique<BagImageStream>(reader_, topics.cam0);
    if (options.stereo) right_ = std::make_unique<BagImageStream>(reader_, topics.cam1);
  }

  std::optional<sensors::FrameBundle> next() override {
    if (next_ >= frames_.size()) return std::nullopt;
    sensors::FrameBundle bundle;
    bundle.index = next_;
    bundle.t_ns = frames_[next_];
    bundle.image0 = imageAt(*left_, bundle.t_ns, camera0_);
    if (right_) bundle.image1 = imageAt(*right_, bundle.t_ns, *camera1_);
    if (options_.inertial) {
      const TimeNs t_prev = next_ == 0 ? bundle.t_ns : frames_[next_ - 1];
      bundle.imu = io::bracketingImu(imu_samples_, t_prev, bundle.t_ns);
    }
    if (const auto gt = groundTruthNear(bundle.t_ns)) bundle.T_w_b_gt = gt->T_w_b;
    ++next_;
    return bundle;
  }

  std::size_t size() const override { return frames_.size(); }
  const sensors::CameraCalibration& camera0() const override { return camera0_; }
  const std::optional<sensors::CameraCalibration>& camera1() const override { return camera1_; }
  const std::optional<sensors::ImuCalibration>& imu() const override { return imu_; }
  const std::vector<std::string>& warnings() const override { return warnings_; }

  Trajectory groundTruth() const override {
    Trajectory served;
    if (frames_.empty()) return served;
    for (const sensors::GroundTruthState& state : ground_truth_) {
      if (state.t_ns + kGroundTruthToleranceNs >= frames_.front() &&
          state.t_ns <= frames_.back() + kGroundTruthToleranceNs) {
        served.push_back({state.t_ns, state.T_w_b});
      }
    }
    return served;
  }

 private:
  /// The camera and IMU rates of the bag (median stamp intervals), for a calibration format that
  /// carries none (VINS); the defaults where a stream is too short.
  io::SensorRates measuredRates() const {
    io::SensorRates rates;
    const auto median_rate = [](std::vector<TimeNs> stamps, double fallback) {
      std::vector<TimeNs> gaps;
      for (std::size_t i = 1; i < stamps.size(); ++i)
        if (stamps[i] > stamps[i - 1]) gaps.push_back(stamps[i] - stamps[i - 1]);
      if (gaps.empty()) return fallback;
      std::nth_element(gaps.begin(), gaps.begin() + gaps.size() / 2, gaps.end());
      return 1e9 / static_cast<double>(gaps[gaps.size() / 2]);
    };
    rates.camera_hz = median_rate(frames_, rates.camera_hz);
    std::vector<TimeNs> imu_stamps;
    for (const sensors::ImuSample& sample : imu_samples_)
      imu_stamps.push_back(sample.t_ns);
    rates.imu_hz = median_rate(std::move(imu_stamps), rates.imu_hz);
    return rates;
  }

  /// One IMU topic, or an accelerometer and a gyroscope topic merged at the gyroscope's stamps.
  void readImu() {
    const auto stamp_of = [](const sensors::ImuSample& sample) { return sample.t_ns; };
    if (!topics_.imu.empty()) {
      imu_samples_ = reader_.imuSamples(topics_.imu);
      requireStampOrder(imu_samples_, stamp_of, reader_.path(), topics_.imu);
      return;
    }
    if (topics_.accel.empty() || topics_.gyro.empty()) {
      throw OptionError("--topics", "an inertial mode needs an IMU topic or accel and gyro topics");
    }
    const std::vector<sensors::ImuSample> accel = reader_.imuSamples(topics_.accel);
    const std::vector<sensors::ImuSample> gyro = reader_.imuSamples(topics_.gyro);
    requireStampOrder(accel, stamp_of, reader_.path(), topics_.accel);
    requireStampOrder(gyro, stamp_of, reader_.path(), topics_.gyro);
    sensors::MergedImu merged = sensors::mergeImuStreams(accel, gyro);
    if (merged.outside + merged.in_gaps > 0) {
      warnings_.push_back(fmt::format(
          "{}: {} of {} {} samples left out of the merged IMU stream ({} outside the {} samples' "
          "time range, {} in gaps of more than 100 ms between them)",
          reader_.path().string(), merged.outside + merged.in_gaps, gyro.size(), topics_.gyro,
          merged.outside, topics_.accel, merged.in_gaps));
    }
    imu_samples_ = std::move(merged.samples);
  }

  /// The ground-truth file when given, else the ground-truth topic when the bag has it.
  void readGroundTruth(const fs::path& file) {
    if (!file.empty()) {
      for (const StampedPose& pose : io::readTrajectory(file))
        ground_truth_.push_back({.t_ns = pose.t_ns, .T_w_b = pose.T_w_x});
      requireStampOrder(
          ground_truth_, [](const auto& state) { return state.t_ns; }, file, "ground truth");
      return;
    }
    if (topics_.ground_truth.empty() || !hasTopic(reader_, topics_.ground_truth)) return;
    ground_truth_ = reader_.groundTruth(topics_.ground_truth);
    requireStampOrder(
        ground_truth_, [](const auto& state) { return state.t_ns; }, reader_.path(),
        topics_.ground_truth);
  }

  /// The served frame times: left stamps (with a right image of the same stamp in stereo, and
  /// inside the IMU's range with IMU), then first_frame and max_frames.
  void selectFrames() {
    const auto itself = [](TimeNs t) { return t; };
    std::vector<TimeNs> left = reader_.imageStamps(topics_.cam0);
    requireStampOrder(left, itself, reader_.path(), topics_.cam0);
    if (options_.stereo) {
      const std::vector<TimeNs> right = reader_.imageStamps(topics_.cam1);
      requireStampOrder(right, itself, reader_.path(), topics_.cam1);
      std::vector<TimeNs> paired;
      std::set_intersection(left.begin(), left.end(), right.begin(), right.end(),
                            std::back_inserter(paired));
      if (paired.size() < left.size()) {
        warnings_.push_back(fmt::format("{}: {} of {} {} images have no {} image of the same stamp",
                                        reader_.path().string(), left.size() - paired.size(),
                                        left.size(), topics_.cam0, topics_.cam1));
      }
      left = std::move(paired);
    }
    if (options_.inertial) {
      std::erase_if(left, [&](TimeNs t) {
        return imu_samples_.empty() || t < imu_samples_.front().t_ns ||
               t > imu_samples_.back().t_ns;
      });
    }
    if (options_.first_frame >= left.size()) {
      throw OptionError("first-frame",
                        fmt::format("{} has only {} usable frames, cannot skip {}",
                                    reader_.path().string(), left.size(), options_.first_frame));
    }
    left.erase(left.begin(), left.begin() + static_cast<std::ptrdiff_t>(options_.first_frame));
    if (options_.max_frames > 0 && left.size() > options_.max_frames)
      left.resize(options_.max_frames);
    frames_ = std::move(left);
  }

  /// The image of `stream` stamped t_ns (earlier ones skipped), grey 8-bit, checked against the
  /// camera's calibrated size.
  cv::Mat imageAt(BagImageStream& stream, TimeNs t_ns,
                  const sensors::CameraCalibration& camera) const {
    while (std::optional<BagImage> image = stream.next()) {
      if (image->t_ns < t_ns) continue;
      if (image->t_ns > t_ns) break;
      if (image->image.cols != camera.width || image->image.rows != camera.height) {
        throw InputError(
            InputLocation{reader_.path()},
            fmt::format("{} image at {} ns is {}x{}, the calibration says {}x{}", camera.name, t_ns,
                        image->image.cols, image->image.rows, camera.width, camera.height));
      }
      return toGray8(image->image);
    }
    throw InputError(
        InputLocation{reader_.path()},
        fmt::format("no {} image stamped {} ns (messages out of stamp order?)", camera.name, t_ns));
  }

  std::optional<sensors::GroundTruthState> groundTruthNear(TimeNs t_ns) const {
    const auto by_time = [](const sensors::GroundTruthState& s, TimeNs t) { return s.t_ns < t; };
    auto it = std::lower_bound(ground_truth_.begin(), ground_truth_.end(), t_ns, by_time);
    std::optional<sensors::GroundTruthState> best;
    for (auto c : {it, it == ground_truth_.begin() ? it : std::prev(it)}) {
      if (c == ground_truth_.end() || std::abs(c->t_ns - t_ns) > kGroundTruthToleranceNs) continue;
      if (!best || std::abs(c->t_ns - t_ns) < std::abs(best->t_ns - t_ns)) best = *c;
    }
    return best;
  }

  RosbagReader reader_;
  BagTopics topics_;
  io::DatasetSourceOptions options_;
  sensors::CameraCalibration camera0_;
  std::optional<sensors::CameraCalibration> camera1_;
  std::optional<sensors::ImuCalibration> imu_;
  std::vector<sensors::ImuSample> imu_samples_;
  std::vector<sensors::GroundTruthState> ground_truth_;
  std::vector<TimeNs> frames_;
  std::vector<std::string> warnings_;
  std::unique_ptr<BagImageStream> left_, right_;
  std::size_t next_ = 0;
};

}  // namespace

BagTopics bagTopicsPreset(const std::string& name) {
  if (name == "viode" || name == "euroc") return BagTopics{};
  if (name == "tumvi") {
    BagTopics topics;
    topics.ground_truth = "/vrpn_client/raw_transform";
    return topics;
  }
  if (name == "openloris") {
    return BagTopics{.cam0 = "/d400/color/image_raw",
                     .cam1 = "",
                     .imu = "",
                     .accel = "/d400/accel/sample",
                     .gyro = "/d400/gyro/sample",
                     .ground_truth = ""};
  }
  throw OptionError(
      "--topics",
      fmt::format("expected viode, euroc, tumvi, openloris or a topic file, got '{}'", name));
}

BagTopics readBagTopics(const fs::path& file) {
  const io::YamlFile yaml = io::YamlFile::load(file);
  if (!yaml.root().IsMap()) throw InputError(InputLocation{file}, "expected a map of topics");
  static const std::vector<std::string> kKeys = {"cam0",  "cam1", "imu",
                                                 "accel", "gyro", "ground_truth"};
  for (const auto& entry : yaml.root()) {
    const std::string key = entry.first.as<std::string>();
    if (std::find(kKeys.begin(), kKeys.end(), key) == kKeys.end()) {
      throw InputError(yaml.at(entry.first, key),
                       "unknown key (cam0, cam1, imu, accel, gyro, ground_truth)");
    }
  }
  const auto topic = [&](const std::string& key) {
    return yaml.has(key) ? yaml.scalar(yaml.child(key), key) : std::string();
  };
  BagTopics topics{.cam0 = topic("cam0"),
                   .cam1 = topic("cam1"),
                   .imu = topic("imu"),
                   .accel = topic("accel"),
                   .gyro = topic("gyro"),
                   .ground_truth = topic("ground_truth")};
  if (topics.cam0.empty()) throw InputError(InputLocation{file, 0, "cam0"}, "missing");
  if (!topics.imu.empty() && (!topics.accel.empty() || !topics.gyro.empty())) {
    throw InputError(InputLocation{file, 0, "imu"},
                     "give either imu or accel and gyro (published apart), not both");
  }
  return topics;
}

BagTopics bagTopics(const std::string& preset_or_file) {
  if (fs::is_regular_file(preset_or_file)) return readBagTopics(preset_or_file);
  return bagTopicsPreset(preset_or_file);
}

std::unique_ptr<io::DatasetSource> openBagSource(const fs::path& bag, const fs::path& calibration,
                                                 const BagTopics& topics,
                                                 const io::DatasetSourceOptions& options,
                                                 const fs::path& ground_truth_file) {
  return std::make_unique<BagSource>(bag, calibration, topics, options, ground_truth_file);
}

}  // namespace superdyna::bag
