#include "superdyna/sim/sequence_generator.h"

#include <fmt/format.h>

#include <algorithm>
#include <chrono>
#include <cmath>
#include <fstream>
#include <limits>
#include <map>
#include <opencv2/features2d.hpp>
#include <opencv2/imgcodecs.hpp>
#include <opencv2/imgproc.hpp>
#include <random>
#include <set>

#include "superdyna/core/error.h"
#include "superdyna/io/yaml_file.h"
#include "superdyna/sim/renderer.h"
#include "superdyna/sim/se3_spline.h"

namespace superdyna::sim {

namespace fs = std::filesystem;

namespace {

/// Agents with at least this many pixels count as "in view".
constexpr int kInViewPixels = 50;
/// FAST threshold of the corners counted in frame_stats.csv (ORB-SLAM's initial threshold).
constexpr int kCornerThreshold = 20;

// ---------------------------------------------------------------- output folder and files

void prepareOutputFolder(const fs::path& dir, bool overwrite) {
  if (fs::exists(dir) && !fs::is_directory(dir)) {
    throw InputError(InputLocation(dir), "exists and is not a folder");
  }
  if (fs::exists(dir) && !fs::is_empty(dir) && !overwrite) {
    throw InputError(InputLocation(dir),
                     "output folder is not empty; choose another or pass --overwrite");
  }
  for (const char* sub : {"mav0/cam0/data", "mav0/cam1/data", "mav0/cam0/mask", "mav0/cam1/mask",
                          "mav0/imu0", "mav0/state_groundtruth_estimate0"}) {
    fs::create_directories(dir / sub);
  }
}

std::ofstream openForWriting(const fs::path& file) {
  std::ofstream out(file);
  if (!out) throw InputError(InputLocation(file), "cannot open file for writing");
  out.precision(17);
  return out;
}

void writeImage(const fs::path& file, const cv::Mat& image) {
  // Fast PNG compression: the sequence has thousands of images and PNG is lossless anyway.
  if (!cv::imwrite(file.string(), image, {cv::IMWRITE_PNG_COMPRESSION, 1})) {
    throw InputError(InputLocation(file), "cannot write image");
  }
}

std::string matrixRows(const Eigen::Matrix4d& M) {
  std::string rows;
  for (int r = 0; r < 4; ++r) {
    rows += fmt::format("{}{:.12g}, {:.12g}, {:.12g}, {:.12g}", r == 0 ? "" : ",\n         ",
                        M(r, 0), M(r, 1), M(r, 2), M(r, 3));
  }
  return rows;
}

std::string sensorHeader(const std::string& type, const std::string& comment, const SE3d& T_b_s) {
  return fmt::format(
      "%YAML:1.0\nsensor_type: {}\ncomment: {}\n\n# Sensor extrinsics wrt. the body-frame.\n"
      "T_BS:\n  cols: 4\n  rows: 4\n  data: [{}]\n",
      type, comment, matrixRows(T_b_s.matrix()));
}

void writeCameraYaml(const fs::path& file, const std::string& name, const RigOptions& rig,
                     const SE3d& T_b_c) {
  const CameraModel camera = rig.cameraModel();
  // With no distortion, zero radial-tangential coefficients: every EuRoC reader accepts them.
  std::vector<double> k = camera.coefficients();
  k.resize(4, 0.0);
  auto out = openForWriting(file);
  out << sensorHeader("camera", "SuperDynaSLAM simulated " + name, T_b_c)
      << fmt::format(
             "\n# Camera specific definitions.\nrate_hz: {}\nresolution: [{}, {}]\n"
             "camera_model: pinhole\nintrinsics: [{}, {}, {}, {}] #fu, fv, cu, cv\n"
             "distortion_model: radial-tangential\ndistortion_coefficients: [{}, {}, {}, {}]\n",
             rig.camera_rate_hz, rig.width, rig.height, rig.fx, rig.fy, rig.cx, rig.cy, k[0], k[1],
             k[2], k[3]);
}

/// The simulated IMU's measurement range, the largest settings of common MEMS IMUs: +-2000 deg/s
/// and +-16 g. Readings are clipped to it (ordinary motions stay far inside).
constexpr double kGyroscopeRange = 2000.0 * M_PI / 180.0;  // [rad/s]
constexpr double kAccelerometerRange = 16.0 * 9.80665;     // [m/s^2]

void writeImuYaml(const fs::path& file, const ImuNoiseOptions& imu, const SE3d& T_b_i) {
  auto out = openForWriting(file);
  out << sensorHeader("imu", "SuperDynaSLAM simulated IMU (EuRoC ADIS16448-like noise)", T_b_i)
      << fmt::format(
             "rate_hz: {}\n\n# inertial sensor noise model parameters (static)\n"
             "gyroscope_noise_density: {:.6e}     # [ rad / s / sqrt(Hz) ]\n"
             "gyroscope_random_walk: {:.6e}       # [ rad / s^2 / sqrt(Hz) ]\n"
             "accelerometer_noise_density: {:.6e} # [ m / s^2 / sqrt(Hz) ]\n"
             "accelerometer_random_walk: {:.6e}   # [ m / s^3 / sqrt(Hz) ]\n\n"
             "# measurement range (readings beyond are clipped)\n"
             "gyroscope_range: {:.9g}       # [ rad / s ]\n"
             "accelerometer_range: {:.9g}   # [ m / s^2 ]\n",
             imu.rate_hz, imu.gyroscope_noise_density, imu.gyroscope_random_walk,
             imu.accelerometer_noise_density, imu.accelerometer_random_walk, kGyroscopeRange,
             kAccelerometerRange);
}

/// A reading clipped to the sensor's range; at the range itself (with the true sign) when
/// `saturate`.
Eigen::Vector3d clipped(const Eigen::Vector3d& v, double range, bool saturate) {
  Eigen::Vector3d out;
  for (int i = 0; i < 3; ++i)
    out[i] = saturate ? std::copysign(range, v[i]) : std::clamp(v[i], -range, range);
  return out;
}

/// imu0/data.csv; the rows in faults.imu_gaps are left out, those in faults.imu_nan written as
/// "nan", those in faults.imu_saturated at the range (times in seconds after t_first_ns, the first
/// frame); every timestamp is written faults.imu_time_offset_s late; rows repeated and swapped as
/// faultyRowOrder() says.
void writeImuData(const fs::path& file, const ImuSequence& imu, const SensorFaultOptions& faults,
                  TimeNs t_first_ns) {
  std::vector<TimedRow> rows;
  rows.reserve(imu.measurements.size());
  const TimeNs offset_ns = secondsToNs(faults.imu_time_offset_s);
  for (const ImuMeasurement& m : imu.measurements) {
    const double t_s = nsToSeconds(m.t_ns - t_first_ns);
    if (inAnyInterval(faults.imu_gaps, t_s)) continue;
    const TimeNs stamp_ns = m.t_ns + offset_ns;
    if (inAnyInterval(faults.imu_nan, t_s)) {
      rows.push_back({t_s, fmt::format("{},nan,nan,nan,nan,nan,nan", stamp_ns)});
      continue;
    }
    const bool saturate = inAnyInterval(faults.imu_saturated, t_s);
    const Eigen::Vector3d w = clipped(m.gyro, kGyroscopeRange, saturate);
    const Eigen::Vector3d a = clipped(m.accel, kAccelerometerRange, saturate);
    rows.push_back({t_s, fmt::format("{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}", stamp_ns,
                                     w.x(), w.y(), w.z(), a.x(), a.y(), a.z())});
  }
  auto out = openForWriting(file);
  out << "#timestamp [ns],w_RS_S_x [rad s^-1],w_RS_S_y [rad s^-1],w_RS_S_z [rad s^-1],"
         "a_RS_S_x [m s^-2],a_RS_S_y [m s^-2],a_RS_S_z [m s^-2]\n";
  for (const std::string& row : faultyRowOrder(rows, faults))
    out << row << '\n';
}

void writeGroundTruth(const fs::path& folder, const ImuSequence& imu) {
  {
    auto yaml = openForWriting(folder / "sensor.yaml");
    // The ground truth is the body's pose and velocity (the IMU's only when it is the body frame)
    // and the IMU's biases in the IMU frame.
    yaml << sensorHeader("visual-inertial", "SuperDynaSLAM simulation ground truth", SE3d());
  }
  auto out = openForWriting(folder / "data.csv");
  out << "#timestamp, p_RS_R_x [m], p_RS_R_y [m], p_RS_R_z [m], q_RS_w [], q_RS_x [], q_RS_y [], "
         "q_RS_z [], v_RS_R_x [m s^-1], v_RS_R_y [m s^-1], v_RS_R_z [m s^-1], "
         "b_w_RS_S_x [rad s^-1], b_w_RS_S_y [rad s^-1], b_w_RS_S_z [rad s^-1], "
         "b_a_RS_S_x [m s^-2], b_a_RS_S_y [m s^-2], b_a_RS_S_z [m s^-2]\n";
  for (const ImuState& s : imu.states) {
    const auto& p = s.T_w_b.t;
    const auto& q = s.T_w_b.q;
    out << fmt::format(
        "{},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},"
        "{:.17g},{:.17g},{:.17g},{:.17g},{:.17g},{:.17g}\n",
        s.t_ns, p.x(), p.y(), p.z(), q.w(), q.x(), q.y(), q.z(), s.v_w.x(), s.v_w.y(), s.v_w.z(),
        s.bg.x(), s.bg.y(), s.bg.z(), s.ba.x(), s.ba.y(), s.ba.z());
  }
}

void writeInstances(const fs::path& file, const std::vector<AgentRecord>& agents) {
  auto out = openForWriting(file);
  out << "# id,class,moving,t_begin_ns,t_end_ns   (moving: 1 if the agent moves at some time)\n";
  for (const AgentRecord& a : agents) {
    out << fmt::format("{},{},{},{},{}\n", a.instance_id, toString(a.object_class),
                       a.ever_moving ? 1 : 0, a.t_begin_ns, a.t_end_ns);
  }
}

// ---------------------------------------------------------------- textures from photos

std::vector<cv::Mat> loadPhotos(const fs::path& dir) {
  if (!fs::is_directory(dir)) throw InputError(InputLocation(dir), "texture folder not found");
  std::vector<fs::path> files;
  for (const auto& entry : fs::recursive_directory_iterator(dir)) {
    const std::string ext = entry.path().extension().string();
    if (ext == ".png" || ext == ".jpg" || ext == ".jpeg" || ext == ".PNG" || ext == ".JPG") {
      files.push_back(entry.path());
    }
  }
  std::sort(files.begin(), files.end());  // directory order is not deterministic
  constexpr std::size_t kMaxPhotos = 64;
  if (files.size() > kMaxPhotos) files.resize(kMaxPhotos);
  std::vector<cv::Mat> photos;
  for (const fs::path& file : files) {
    cv::Mat image = cv::imread(file.string(), cv::IMREAD_GRAYSCALE);
    if (image.empty()) throw InputError(InputLocation(file), "cannot read image");
    photos.push_back(std::move(image));
  }
  if (photos.empty()) throw InputError(InputLocation(dir), "no .png or .jpg images in folder");
  return photos;
}

// ---------------------------------------------------------------- per-frame bookkeeping

/// Pixel count of every instance id in a mask.
std::map<std::uint16_t, int> countInstances(const cv::Mat& mask) {
  std::map<std::uint16_t, int> counts;
  for (int r = 0; r < mask.rows; ++r) {
    const auto* row = mask.ptr<std::uint16_t>(r);
    for (int c = 0; c < mask.cols; ++c) {
      if (row[c] != 0) ++counts[row[c]];
    }
  }
  return counts;
}

/// The instance mask a segmenter is given: the rendered one without the unlabelled agents (their
/// pixels read as background).
cv::Mat labelledMask(const cv::Mat& instance, const std::set<std::uint16_t>& unlabelled) {
  if (unlabelled.empty()) return instance;
  cv::Mat mask = instance.clone();
  for (int r = 0; r < mask.rows; ++r) {
    auto* row = mask.ptr<std::uint16_t>(r);
    for (int c = 0; c < mask.cols; ++c) {
      if (row[c] != 0 && unlabelled.contains(row[c])) row[c] = 0;
    }
  }
  return mask;
}

/// What one cam0 frame shows of the agents.
struct FrameContent {
  int moving_in_view = 0;  ///< Moving agents with at least kInViewPixels pixels.
  int agent_pixels = 0;
  int moving_pixels = 0;             ///< On agents moving at the frame's time.
  int unlabelled_moving_pixels = 0;  ///< Of those, on unlabelled agents.
  int corners = 0;                   ///< FAST corners in the image.
  int moving_corners = 0;            ///< Of those, on moving agents.
};

/// Per-frame shares of moving pixels and corners, and their mean and maximum.
class MovingShareStats {
 public:
  void add(const FrameContent& frame, int image_pixels) {
    const double pixels = double(frame.moving_pixels) / image_pixels;
    const double corners = frame.corners > 0 ? double(frame.moving_corners) / frame.corners : 0.0;
    sum_pixels_ += pixels;
    sum_unlabelled_ += double(frame.unlabelled_moving_pixels) / image_pixels;
    sum_corners_ += corners;
    max_pixels_ = std::max(max_pixels_, pixels);
    max_corners_ = std::max(max_corners_, corners);
    ++frames_;
  }
  void summarize(SimulationSummary* summary) const {
    if (frames_ == 0) return;
    summary->mean_moving_coverage = sum_pixels_ / frames_;
    summary->max_moving_coverage = max_pixels_;
    summary->mean_unlabelled_moving_coverage = sum_unlabelled_ / frames_;
    summary->mean_moving_corner_share = sum_corners_ / frames_;
    summary->max_moving_corner_share = max_corners_;
  }

 private:
  double sum_pixels_ = 0.0, sum_unlabelled_ = 0.0, sum_corners_ = 0.0;
  double max_pixels_ = 0.0, max_corners_ = 0.0;
  int frames_ = 0;
};

/// Fraction of an image's pixels that see a surface: finite depth (the rest is the sky).
double surfaceShare(const RenderResult& render) {
  int surface_pixels = 0;
  for (int r = 0; r < render.depth.rows; ++r) {
    const auto* row = render.depth.ptr<float>(r);
    for (int c = 0; c < render.depth.cols; ++c)
      surface_pixels += std::isfinite(row[c]) ? 1 : 0;
  }
  return double(surface_pixels) / (render.depth.rows * render.depth.cols);
}

cv::Vec3b segmentationColour(std::uint16_t id) {
  if (id == 0) return {70, 70, 70};
  // A fixed pseudo-random bright colour per id (deterministic across runs and machines).
  std::uint32_t h = id * 2654435761u;
  h ^= h >> 15;
  return {static_cast<uchar>(64 + (h & 0x7F) + 64), static_cast<uchar>(64 + ((h >> 8) & 0x7F)),
          static_cast<uchar>(64 + ((h >> 16) & 0x7F) + 32)};
}

cv::Mat colourSegmentation(const cv::Mat& mask) {
  cv::Mat colour(mask.size(), CV_8UC3);
  for (int r = 0; r < mask.rows; ++r) {
    const auto* in = mask.ptr<std::uint16_t>(r);
    auto* out = colour.ptr<cv::Vec3b>(r);
    for (int c = 0; c < mask.cols; ++c)
      out[c] = segmentationColour(in[c]);
  }
  return colour;
}

struct Landmark {
  Eigen::Vector3d p_w;
  TimeNs t_ns;
};

/// Random static-surface points seen by cam0 in this frame (exactly on the rendered surfaces).
void sampleLandmarks(const RenderResult& render, const CameraModel& camera, const SE3d& T_w_c,
                     TimeNs t_ns, int count, std::mt19937_64& rng,
                     std::vector<Landmark>* landmarks) {
  std::uniform_int_distribution<int> u(0, camera.width() - 1), v(0, camera.height() - 1);
  for (int tries = 0, added = 0; added < count && tries < 20 * count; ++tries) {
    const int x = u(rng), y = v(rng);
    const float depth = render.depth.at<float>(y, x);
    if (render.instance.at<std::uint16_t>(y, x) != 0 || !std::isfinite(depth)) continue;
    const auto bearing = camera.unproject(Eigen::Vector2d(x, y));
    if (!bearing || bearing->z() <= 0.0) continue;
    landmarks->push_back({T_w_c * (*bearing * (depth / bearing->z())), t_ns});
    ++added;
  }
}

void writeLandmarks(const fs::path& file, const std::vector<Landmark>& landmarks) {
  auto out = openForWriting(file);
  out << "# id,x [m],y [m],z [m],t_ns (a frame whose cam0 sees it)\n";
  for (std::size_t i = 0; i < landmarks.size(); ++i) {
    const auto& p = landmarks[i].p_w;
    out << fmt::format("{},{:.9f},{:.9f},{:.9f},{}\n", i, p.x(), p.y(), p.z(), landmarks[i].t_ns);
  }
}

double proceduralExtent(SceneType scene) {
  switch (scene) {
    case SceneType::kIndoor:
      return 3.0;
    case SceneType::kParking:
      return 12.0;
    case SceneType::kStreet:
      return 25.0;
  }
  return 10.0;
}

std::vector<TimeNs> frameTimes(const TimeRange& window, double rate_hz) {
  std::vector<TimeNs> times;
  for (std::int64_t k = 0;; ++k) {
    const TimeNs t = window.begin + static_cast<TimeNs>(std::llround(k * 1e9 / rate_hz));
    if (t > window.end) break;
    times.push_back(t);
  }
  return times;
}

/// Exposure gains and motion blur over the sequence, for the summary.
class PhotometricStats {
 public:
  void add(const std::array<double, 2>& gains, const RenderResult& left,
           const RenderResult& right) {
    for (const double gain : gains) {
      min_gain_ = std::min(min_gain_, gain);
      max_gain_ = std::max(max_gain_, gain);
    }
    for (const RenderResult* image : {&left, &right}) {
      samples_sum_ += image->blur_samples;
      motion_sum_ += image->exposure_motion_px;
      max_motion_ = std::max(max_motion_, image->exposure_motion_px);
      ++images_;
    }
  }

  void summarize(SimulationSummary* summary) const {
    if (images_ == 0) return;
    summary->mean_blur_samples = samples_sum_ / images_;
    summary->mean_exposure_motion_px = motion_sum_ / images_;
    summary->max_exposure_motion_px = max_motion_;
    summary->min_gain = min_gain_;
    summary->max_gain = max_gain_;
  }

 private:
  double min_gain_ = std::numeric_limits<double>::infinity();
  double max_gain_ = -std::numeric_limits<double>::infinity();
  double samples_sum_ = 0.0, motion_sum_ = 0.0, max_motion_ = 0.0;
  int images_ = 0;
};

/// Everything the frame loop needs, prepared once.
class SequenceWriter {
 public:
  SequenceWriter(const SimulationOptions& options, const Se3Spline& spline, const World& world,
                 std::vector<TimeNs> frame_times)
      : options_(options),
        spline_(spline),
        world_(world),
        frame_times_(std::move(frame_times)),
        illumination_(options.illumination, options.seed, frame_times_.front()),
        camera_(options.rig.cameraModel()),
        renderers_{Renderer(camera_), Renderer(camera_)},
        T_b_c_{options.rig.T_b_c0(), options.rig.T_b_c1()},
        rng_(options.seed ^ 0x5eedULL),
        mav0_(options.output_dir / "mav0") {
    for (const AgentRecord& agent : world_.agents) {
      if (agent.object_class == ObjectClass::kUnlabelled) unlabelled_.insert(agent.instance_id);
    }
  }

  void run(const ProgressCallback& progress, SimulationSummary* summary) {
    std::vector<TimedRow> rows0, rows1;  // written at the end, with the faults' row order
    auto states = openForWriting(mav0_ / "instance_states.csv");
    std::optional<std::ofstream> photometric;
    if (photometricEffectsOn()) {
      photometric = openForWriting(mav0_ / "photometric.csv");
      *photometric << "# t_ns,gain_cam0,gain_cam1,blur_samples_cam0,blur_samples_cam1,"
                      "exposure_motion_px_cam0,exposure_motion_px_cam1   (exposure centred on "
                      "t_ns)\n";
    }
    PhotometricStats stats;
    states << "# t_ns,id,moving,pixels_cam0,pixels_cam1,class   (agents seen by either camera; "
              "pixels as rendered, unlabelled agents included)\n";
    auto frame_stats = openForWriting(mav0_ / "frame_stats.csv");
    frame_stats << "# t_ns,agent_pixels,moving_pixels,unlabelled_moving_pixels,moving_in_view,"
                   "corners,moving_corners   (cam0; moving: agents moving at t_ns; corners: FAST "
                   "threshold 20 on the image)\n";
    MovingShareStats moving_shares;
    const int per_frame_landmarks =
        static_cast<int>(std::ceil(double(options_.landmark_count) / frame_times_.size()));
    double in_view_sum = 0.0, coverage_sum = 0.0, surface_sum = 0.0;
    for (std::size_t k = 0; k < frame_times_.size(); ++k) {
      const TimeNs t = frame_times_[k];
      const std::string name = fmt::format("{}.png", t);
      RenderResult left = renderCamera(0, t);
      RenderResult right = renderCamera(1, t);
      const double t_s = nsToSeconds(t - frame_times_.front());
      applyImageFaults(t_s, left, right);
      writeFrame(0, name, left);
      rows0.push_back({t_s, fmt::format("{},{}", t, name)});
      if (!inAnyInterval(options_.faults.missing_cam1, t_s)) {
        writeFrame(1, name, right);
        rows1.push_back({t_s, fmt::format("{},{}", t, name)});
      }
      const std::array<double, 2> gains = {illumination_.gain(0, t), illumination_.gain(1, t)};
      stats.add(gains, left, right);
      if (photometric) {
        *photometric << fmt::format("{},{:.9g},{:.9g},{},{},{:.3f},{:.3f}\n", t, gains[0], gains[1],
                                    left.blur_samples, right.blur_samples, left.exposure_motion_px,
                                    right.exposure_motion_px);
      }
      FrameContent content = writeInstanceStates(states, t, left, right);
      countCorners(t, left, &content);
      const int image_pixels = left.instance.rows * left.instance.cols;
      coverage_sum += double(content.agent_pixels) / image_pixels;
      moving_shares.add(content, image_pixels);
      frame_stats << fmt::format("{},{},{},{},{},{},{}\n", t, content.agent_pixels,
                                 content.moving_pixels, content.unlabelled_moving_pixels,
                                 content.moving_in_view, content.corners, content.moving_corners);
      const int in_view = content.moving_in_view;
      in_view_sum += in_view;
      surface_sum += surfaceShare(left);
      summary->max_moving_in_view = std::max(summary->max_moving_in_view, double(in_view));
      if (static_cast<int>(landmarks_.size()) < options_.landmark_count) {
        sampleLandmarks(left, camera_, cameraPose(0, t), t, per_frame_landmarks, rng_, &landmarks_);
      }
      if (options_.preview_path && k == previewIndex()) writePreview(left);
      if (progress) progress(static_cast<int>(k) + 1, static_cast<int>(frame_times_.size()));
    }
    writeCameraRows(mav0_ / "cam0/data.csv", rows0);
    writeCameraRows(mav0_ / "cam1/data.csv", rows1);
    if (static_cast<int>(landmarks_.size()) > options_.landmark_count) {
      landmarks_.resize(static_cast<std::size_t>(options_.landmark_count));
    }
    if (options_.landmark_count > 0) writeLandmarks(mav0_ / "landmarks.csv", landmarks_);
    summary->frames = static_cast<int>(frame_times_.size());
    summary->mean_moving_in_view = in_view_sum / frame_times_.size();
    summary->mean_agent_coverage = coverage_sum / frame_times_.size();
    summary->mean_surface_coverage = surface_sum / frame_times_.size();
    moving_shares.summarize(summary);
    stats.summarize(summary);
  }

 private:
  SE3d cameraPose(int cam, TimeNs t) const { return spline_.pose(t) * T_b_c_[cam]; }

  void writeCameraRows(const fs::path& csv, const std::vector<TimedRow>& rows) const {
    auto out = openForWriting(csv);
    out << "#timestamp [ns],filename\n";
    for (const std::string& row : faultyRowOrder(rows, options_.faults))
      out << row << '\n';
  }

  /// Black or overexposed images at t_s (after the first frame); masks and ground truth unchanged.
  void applyImageFaults(double t_s, RenderResult& left, RenderResult& right) const {
    if (inAnyInterval(options_.faults.black_frames, t_s)) {
      left.image.setTo(0);  // a covered or failed camera
      right.image.setTo(0);
    }
    if (inAnyInterval(options_.faults.overexposed_frames, t_s)) {
      left.image.setTo(255);  // saturated: exposure far too long, or facing the sun
      right.image.setTo(255);
    }
  }

  std::size_t previewIndex() const {
    return std::min(static_cast<std::size_t>(std::max(options_.preview_frame, 0)),
                    frame_times_.size() - 1);
  }

  /// The frame beside its instance mask (each agent in its own colour), for a quick look.
  void writePreview(const RenderResult& render) const {
    cv::Mat gray_bgr, preview;
    cv::cvtColor(render.image, gray_bgr, cv::COLOR_GRAY2BGR);
    cv::Mat mask = colourSegmentation(render.instance);
    mask.setTo(cv::Scalar(0, 0, 0), render.instance == 0);
    cv::hconcat(gray_bgr, mask, preview);
    if (options_.preview_path->has_parent_path()) {
      fs::create_directories(options_.preview_path->parent_path());
    }
    if (!cv::imwrite(options_.preview_path->string(), preview)) {
      throw InputError(InputLocation(*options_.preview_path), "cannot write preview image");
    }
  }

  bool photometricEffectsOn() const {
    return options_.illumination.active() || options_.motion_blur_exposure_s > 0.0;
  }

  RenderOptions renderOptions(int cam, TimeNs t) const {
    RenderOptions render;
    render.gain = illumination_.gain(cam, t);
    render.noise_sigma = options_.noise ? options_.pixel_noise_sigma : 0.0;
    render.seed = options_.seed * 2 + static_cast<std::uint64_t>(cam);
    if (options_.motion_blur_exposure_s > 0.0) {
      render.blur_samples = options_.motion_blur_samples;
      render.exposure_s = options_.motion_blur_exposure_s;
      render.blur_step_px = options_.motion_blur_step_px;
      render.max_blur_samples = options_.motion_blur_max_samples;
    }
    return render;
  }

  RenderResult renderCamera(int cam, TimeNs t) const {
    const auto pose_at = [this, cam](TimeNs time) { return cameraPose(cam, time); };
    return renderers_[static_cast<std::size_t>(cam)].render(world_.scene, pose_at, t,
                                                            renderOptions(cam, t));
  }

  void writeFrame(int cam, const std::string& name, const RenderResult& render) const {
    const fs::path folder = mav0_ / fmt::format("cam{}", cam);
    writeImage(folder / "data" / name, render.image);
    const cv::Mat mask = labelledMask(render.instance, unlabelled_);
    writeImage(folder / "mask" / name, mask);
    if (options_.semantic_color) {
      fs::create_directories(folder / "segmentation");
      writeImage(folder / "segmentation" / name, colourSegmentation(mask));
    }
  }

  /// Writes the rows of the agents either camera sees; returns what cam0 shows of them.
  FrameContent writeInstanceStates(std::ofstream& out, TimeNs t, const RenderResult& left,
                                   const RenderResult& right) const {
    const auto counts0 = countInstances(left.instance);
    const auto counts1 = countInstances(right.instance);
    FrameContent content;
    for (const SceneObject& object : world_.scene.objects) {
      if (object.instance_id == 0) continue;
      const auto it0 = counts0.find(object.instance_id);
      const auto it1 = counts1.find(object.instance_id);
      const int n0 = it0 == counts0.end() ? 0 : it0->second;
      const int n1 = it1 == counts1.end() ? 0 : it1->second;
      if (n0 == 0 && n1 == 0) continue;
      const bool moving = isMoving(object, t);
      out << fmt::format("{},{},{},{},{},{}\n", t, object.instance_id, moving ? 1 : 0, n0, n1,
                         toString(object.object_class));
      content.agent_pixels += n0;
      if (!moving) continue;
      content.moving_pixels += n0;
      if (object.object_class == ObjectClass::kUnlabelled) content.unlabelled_moving_pixels += n0;
      if (n0 >= kInViewPixels) ++content.moving_in_view;
    }
    return content;
  }

  static bool isMoving(const SceneObject& object, TimeNs t) {
    return object.is_moving && object.is_moving(t);
  }

  /// FAST corners of the cam0 image, and how many lie on agents moving at t: a detector's view of
  /// the share of features a SLAM front end would extract on movers.
  void countCorners(TimeNs t, const RenderResult& left, FrameContent* content) const {
    std::set<std::uint16_t> moving_ids;
    for (const SceneObject& object : world_.scene.objects) {
      if (object.instance_id != 0 && isMoving(object, t)) moving_ids.insert(object.instance_id);
    }
    std::vector<cv::KeyPoint> corners;
    cv::FAST(left.image, corners, kCornerThreshold, true);
    content->corners = static_cast<int>(corners.size());
    for (const cv::KeyPoint& corner : corners) {
      const int c = std::clamp(static_cast<int>(corner.pt.x), 0, left.instance.cols - 1);
      const int r = std::clamp(static_cast<int>(corner.pt.y), 0, left.instance.rows - 1);
      const std::uint16_t id = left.instance.at<std::uint16_t>(r, c);
      if (id != 0 && moving_ids.contains(id)) ++content->moving_corners;
    }
  }

  const SimulationOptions& options_;
  const Se3Spline& spline_;
  const World& world_;
  std::vector<TimeNs> frame_times_;
  IlluminationSchedule illumination_;
  CameraModel camera_;
  std::array<Renderer, 2> renderers_;
  std::array<SE3d, 2> T_b_c_;
  std::mt19937_64 rng_;
  fs::path mav0_;
  std::vector<Landmark> landmarks_;
  std::set<std::uint16_t> unlabelled_;  ///< Agents left out of the written masks.
};

Se3Spline fitMotion(const MotionWindow& motion, const SimulationOptions& options) {
  const Se3Spline spline = Se3Spline::fit(motion.body_poses, secondsToNs(options.knot_spacing_s));
  const TimeRange valid = spline.validRange();
  if (valid.begin > motion.window.begin || valid.end < motion.window.end) {
    throw InputError(InputLocation(options.motion.trajectory_file.value_or("procedural")),
                     fmt::format("the motion covers {:.2f}..{:.2f} s but the sequence needs "
                                 "{:.2f}..{:.2f} s; shorten --duration or change --start",
                                 nsToSeconds(valid.begin), nsToSeconds(valid.end),
                                 nsToSeconds(motion.window.begin), nsToSeconds(motion.window.end)));
  }
  return spline;
}

std::string blurSamplesText(int samples) {
  return samples == 0 ? std::string("auto") : std::to_string(samples);
}

std::string optionalText(const std::optional<fs::path>& path, const std::string& none) {
  return path ? path->string() : none;
}

void writeWorldSource(std::ostream& out, const WorldSource& w) {
  out << fmt::format(
      "# What rebuilds this sequence's static world (superdyna simulate --world-of).\n"
      "world_source:\n  trajectory: {}\n  trajectory_format: {}\n"
      "  trajectory_times: {}\n  segment: {}\n  motion_convention: {}\n  mount_height_m: {}\n"
      "  start_s: {}\n  duration_s: {}\n  knot_spacing_s: {}\n  scene: {}\n  seed: {}\n"
      "  texture_dir: {}\n  background_contrast: {}\n  texture_variety: {}\n"
      "  static_world_fingerprint: {}\n",
      optionalText(w.motion.trajectory_file, "procedural"), io::toString(w.motion.read.format),
      optionalText(w.motion.read.kitti_times, "none"),
      w.motion.read.segment ? std::to_string(*w.motion.read.segment) : std::string("none"),
      toString(w.motion.convention), w.motion.mount_height_m, w.motion.start_s, w.motion.duration_s,
      w.knot_spacing_s, toString(w.scene), w.seed, optionalText(w.texture_dir, "procedural"),
      w.background_contrast, w.texture_variety, w.fingerprint);
}

void writeSimulationYaml(const fs::path& file, const SimulationOptions& o, const MotionWindow& m,
                         const SimulationSummary& s, const WorldSource& world_source) {
  auto out = openForWriting(file);
  const IlluminationOptions& il = o.illumination;
  out << fmt::format(
      "# SuperDynaSLAM synthetic sequence: effective options and summary\n"
      "trajectory: {}\nmotion_convention: {}\nstart_s: {}\nduration_s: {}\nscene: {}\n"
      "dynamic: {}\ndynamic_pattern: {}\npattern_size: {}\npattern_distance_m: [{}, {}]\n"
      "slow_movers: {}\nunlabelled_share: {}\nbackground_contrast: {}\ntexture_variety: {}\n"
      "parked_density: {}\n"
      "seed: {}\nnoise: {}\npixel_noise_sigma: {}\ndistortion: {}\n"
      "texture_dir: {}\nbaseline_m: {}\ncamera_rate_hz: {}\nimu_rate_hz: {}\n"
      "knot_spacing_s: {}\nimu_offset_m: [{}, {}, {}]\nimu_rotation_deg: [{}, {}, {}]\n",
      o.motion.trajectory_file ? o.motion.trajectory_file->string() : "procedural",
      toString(m.convention), o.motion.start_s, o.motion.duration_s, toString(o.world.scene),
      toString(o.world.dynamic), toString(o.world.pattern.pattern), o.world.pattern.group_size,
      o.world.pattern.min_distance_m, o.world.pattern.max_distance_m, o.world.pattern.slow,
      o.world.unlabelled_share, o.world.background_contrast, o.world.texture_variety,
      o.world.parked_density, o.seed, o.noise, o.pixel_noise_sigma, o.rig.distortion,
      o.texture_dir ? o.texture_dir->string() : "procedural", o.rig.baseline_m,
      o.rig.camera_rate_hz, o.imu.rate_hz, o.knot_spacing_s, o.rig.imu_offset_m.x(),
      o.rig.imu_offset_m.y(), o.rig.imu_offset_m.z(), o.rig.imu_rotation_deg.x(),
      o.rig.imu_rotation_deg.y(), o.rig.imu_rotation_deg.z());
  out << fmt::format(
      "# Image timestamps are mid-exposure; blur averages sub-frames over the exposure.\n"
      "motion_blur:\n  exposure_ms: {}\n  samples: {}\n  step_px: {}\n  max_samples: {}\n"
      "# gain = base_gain * drift * steps * flicker (* stereo_gain_ratio for cam1), applied to\n"
      "# the radiance before noise, clipping to [0, 255] and rounding.\n"
      "illumination:\n  effects: {}\n  base_gain: {}\n  drift_amplitude: {}\n  drift_period_s: {}\n"
      "  step_amplitude: {}\n  step_interval_s: {}\n  flicker_amplitude: {}\n"
      "  stereo_gain_ratio: {}\n",
      1e3 * o.motion_blur_exposure_s, blurSamplesText(o.motion_blur_samples), o.motion_blur_step_px,
      o.motion_blur_max_samples, illuminationModes(il), il.base_gain, il.drift_amplitude,
      il.drift_period_s, il.step_amplitude, il.step_interval_s, il.flicker_amplitude,
      il.stereo_gain_ratio);
  out << fmt::format(
      "summary:\n  frames: {}\n  imu_samples: {}\n"
      "  static_agents: {}\n  moving_agents: {}\n  mean_moving_in_view: {:.3f}\n"
      "  max_moving_in_view: {}\n  mean_agent_coverage: {:.4f}\n  mean_moving_coverage: {:.4f}\n"
      "  max_moving_coverage: {:.4f}\n  mean_unlabelled_moving_coverage: {:.4f}\n"
      "  mean_moving_corner_share: {:.4f}\n  max_moving_corner_share: {:.4f}\n"
      "  mean_surface_coverage: {:.4f}\n"
      "  path_length_m: {:.3f}\n"
      "  mean_blur_samples: {:.3f}\n  mean_exposure_motion_px: {:.3f}\n"
      "  max_exposure_motion_px: {:.3f}\n  min_gain: {:.4f}\n  max_gain: {:.4f}\n",
      s.frames, s.imu_samples, s.static_agents, s.moving_agents, s.mean_moving_in_view,
      s.max_moving_in_view, s.mean_agent_coverage, s.mean_moving_coverage, s.max_moving_coverage,
      s.mean_unlabelled_moving_coverage, s.mean_moving_corner_share, s.max_moving_corner_share,
      s.mean_surface_coverage, s.path_length_m, s.mean_blur_samples, s.mean_exposure_motion_px,
      s.max_exposure_motion_px, s.min_gain, s.max_gain);
  if (o.world_of) out << "world_of: " << o.world_of->sequence.string() << "\n";
  writeWorldSource(out, world_source);
}

std::optional<fs::path> absolute(const std::optional<fs::path>& path) {
  if (!path) return std::nullopt;
  return fs::absolute(*path).lexically_normal();
}

CameraPath cameraPathOf(const Se3Spline& spline, const MotionWindow& motion,
                        const RigOptions& rig) {
  const CameraModel camera = rig.cameraModel();
  CameraPath camera_path;
  const SE3d T_b_c0 = rig.T_b_c0();
  camera_path.T_w_c = [&spline, T_b_c0](TimeNs t) { return spline.pose(t) * T_b_c0; };
  camera_path.range = motion.window;
  camera_path.horizontal_fov_rad = 2.0 * std::atan(0.5 * camera.width() / camera.fx());
  return camera_path;
}

/// This sequence's world: its own, or the static world of options.world_of with its agents; the
/// source its simulation.yaml records. `start_origin_ns`: the camera path's time --start counts
/// from (MotionWindow::start_origin_ns), for the errors of a reused world.
std::pair<World, WorldSource> buildSequenceWorld(const SimulationOptions& options,
                                                 const CameraPath& camera_path,
                                                 TimeNs start_origin_ns) {
  WorldOptions world_options = options.world;
  world_options.seed = options.seed;
  if (!options.world_of) {
    if (options.texture_dir) world_options.photos = loadPhotos(*options.texture_dir);
    World world = buildWorld(world_options, camera_path);
    WorldSource source{fs::absolute(options.output_dir).lexically_normal(),
                       options.motion,
                       options.knot_spacing_s,
                       options.world.scene,
                       options.seed,
                       absolute(options.texture_dir),
                       options.world.background_contrast,
                       options.world.texture_variety,
                       staticWorldFingerprint(world)};
    source.motion.trajectory_file = absolute(options.motion.trajectory_file);
    source.motion.read.kitti_times = absolute(options.motion.read.kitti_times);
    return {std::move(world), std::move(source)};
  }
  const WorldSource& from = *options.world_of;
  SimulationOptions source_options = options;
  source_options.motion = from.motion;
  source_options.knot_spacing_s = from.knot_spacing_s;
  const MotionWindow source_motion = loadMotion(from.motion, proceduralExtent(from.scene));
  const Se3Spline source_spline = fitMotion(source_motion, source_options);
  WorldOptions static_options = world_options;
  static_options.scene = from.scene;
  static_options.seed = from.seed;
  static_options.background_contrast = from.background_contrast;
  static_options.texture_variety = from.texture_variety;
  if (from.texture_dir) static_options.photos = loadPhotos(*from.texture_dir);
  world_options.scene = from.scene;
  world_options.background_contrast = from.background_contrast;
  world_options.texture_variety = from.texture_variety;
  world_options.photos = static_options.photos;
  const ReusedWorldHint hint{
      start_origin_ns,
      fmt::format("the part of the trajectory its world was built around fits: --start {:g} "
                  "--duration {:g} (that sequence's own)",
                  from.motion.start_s, from.motion.duration_s)};
  World world =
      buildWorldIn(static_options, cameraPathOf(source_spline, source_motion, options.rig),
                   world_options, camera_path, hint);
  const std::uint64_t fingerprint = staticWorldFingerprint(world);
  if (fingerprint != from.fingerprint) {
    throw InputError(InputLocation(from.sequence / "simulation.yaml", 0,
                                   "world_source.static_world_fingerprint"),
                     fmt::format("the static world rebuilt from it has fingerprint {}, the "
                                 "sequence recorded {}: its trajectory or texture files changed",
                                 fingerprint, from.fingerprint));
  }
  return {std::move(world), from};
}

}  // namespace

CameraModel RigOptions::cameraModel() const {
  if (!distortion) return CameraModel(width, height, fx, fy, cx, cy);
  return CameraModel(width, height, fx, fy, cx, cy, DistortionModel::kRadialTangential,
                     {-0.28340811, 0.07395907, 0.00019359, 1.76187114e-05});
}

SE3d RigOptions::T_b_c0() const {
  // EuRoC MAV cam0 T_BS (VI-Sensor): the camera looks along the body z axis.
  Eigen::Matrix4d M;
  M << 0.0148655429818, -0.999880929698, 0.00414029679422, -0.0216401454975,  //
      0.999557249008, 0.0149672133247, 0.025715529948, -0.064676986768,       //
      -0.0257744366974, 0.00375618835797, 0.999660727178, 0.00981073058949,   //
      0.0, 0.0, 0.0, 1.0;
  return SE3d::fromMatrix(M);
}

SE3d RigOptions::T_b_c1() const {
  const SE3d T_b_c0_pose = T_b_c0();
  return T_b_c0_pose * SE3d(Eigen::Quaterniond::Identity(), Eigen::Vector3d(baseline_m, 0, 0));
}

SE3d RigOptions::T_b_i() const {
  return SE3d(expSO3(imu_rotation_deg * (M_PI / 180.0)), imu_offset_m);
}

void RigOptions::validate() const {
  cameraModel();  // checks size and intrinsics
  if (!(baseline_m > 0.0)) throw OptionError("baseline", "must be > 0");
  if (!(camera_rate_hz > 0.0)) throw OptionError("camera-rate", "must be > 0");
  if (!imu_offset_m.allFinite()) throw OptionError("imu-offset", "must be finite");
  if (!imu_rotation_deg.allFinite() || !(imu_rotation_deg.norm() < 180.0)) {
    throw OptionError("imu-rotation", "must be a finite rotation vector shorter than 180 deg");
  }
}

void SimulationOptions::validate() const {
  if (output_dir.empty()) throw OptionError("out", "an output folder is required");
  rig.validate();
  world.validate();
  imu.validate();
  illumination.validate();
  faults.validate();
  if (!(motion_blur_exposure_s >= 0.0 && motion_blur_exposure_s <= 0.1)) {
    throw OptionError("exposure-ms", "must be in [0, 100] ms");
  }
  if (motion_blur_samples < 0 || motion_blur_samples > 64) {
    throw OptionError("blur-samples", "must be in [0, 64] (0 = automatic)");
  }
  if (!(motion_blur_step_px >= 0.1 && motion_blur_step_px <= 10.0)) {
    throw OptionError("blur-step", "must be in [0.1, 10] px");
  }
  if (motion_blur_max_samples < 1 || motion_blur_max_samples > 64) {
    throw OptionError("blur-max-samples", "must be in [1, 64]");
  }
  if (pixel_noise_sigma < 0.0) throw OptionError("pixel-noise", "must be >= 0");
  if (landmark_count < 0) throw OptionError("landmarks", "must be >= 0");
  if (!(knot_spacing_s >= 0.01 && knot_spacing_s <= 1.0)) {
    throw OptionError("knot-spacing", "must be in [0.01, 1] s");
  }
}

/// The frame times left after the dropped frames (SensorFaultOptions::dropsFrame) are removed.
std::vector<TimeNs> withoutDroppedFrames(const std::vector<TimeNs>& times,
                                         const SimulationOptions& options) {
  std::vector<TimeNs> kept;
  for (std::size_t k = 0; k < times.size(); ++k) {
    if (!options.faults.dropsFrame(k, options.seed)) kept.push_back(times[k]);
  }
  return kept;
}

SimulationSummary generateSequence(const SimulationOptions& options,
                                   const ProgressCallback& progress) {
  const auto started = std::chrono::steady_clock::now();
  options.validate();
  const MotionWindow motion = loadMotion(options.motion, proceduralExtent(options.world.scene));
  const Se3Spline spline = fitMotion(motion, options);
  prepareOutputFolder(options.output_dir, options.overwrite);

  const CameraPath camera_path = cameraPathOf(spline, motion, options.rig);
  const auto [world, world_source] =
      buildSequenceWorld(options, camera_path, motion.start_origin_ns);

  ImuNoiseOptions imu_options = options.imu;
  imu_options.noise = options.noise;
  imu_options.seed = options.seed;
  const ImuSequence imu =
      ImuSimulator(imu_options, options.rig.T_b_i()).simulate(spline, motion.window);

  const fs::path mav0 = options.output_dir / "mav0";
  writeCameraYaml(mav0 / "cam0/sensor.yaml", "cam0", options.rig, options.rig.T_b_c0());
  writeCameraYaml(mav0 / "cam1/sensor.yaml", "cam1", options.rig, options.rig.T_b_c1());
  writeImuYaml(mav0 / "imu0/sensor.yaml", imu_options, options.rig.T_b_i());
  std::vector<TimeNs> frame_times = frameTimes(motion.window, options.rig.camera_rate_hz);
  writeImuData(mav0 / "imu0/data.csv", imu, options.faults, frame_times.front());
  writeGroundTruth(mav0 / "state_groundtruth_estimate0", imu);
  writeInstances(mav0 / "instances.csv", world.agents);

  SimulationSummary summary;
  summary.imu_samples = imu.measurements.size();
  for (const AgentRecord& agent : world.agents) {
    ++(agent.ever_moving ? summary.moving_agents : summary.static_agents);
  }
  for (std::size_t i = 1; i < imu.states.size(); ++i) {
    summary.path_length_m += (imu.states[i].T_w_b.t - imu.states[i - 1].T_w_b.t).norm();
  }
  SequenceWriter writer(options, spline, world, withoutDroppedFrames(frame_times, options));
  writer.run(progress, &summary);
  if (options.semantic_color) {
    auto colours = openForWriting(mav0 / "segmentation_colors.csv");
    colours << "# id,r,g,b\n0,70,70,70\n";
    for (const AgentRecord& agent : world.agents) {
      const cv::Vec3b bgr = segmentationColour(agent.instance_id);
      colours << fmt::format("{},{},{},{}\n", agent.instance_id, bgr[2], bgr[1], bgr[0]);
    }
  }
  // No wall-clock time in the files: the same seed must give byte-identical output.
  writeSimulationYaml(options.output_dir / "simulation.yaml", options, motion, summary,
                      world_source);
  summary.seconds =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - started).count();
  return summary;
}

WorldSource readWorldSource(const fs::path& sequence) {
  const fs::path file = sequence / "simulation.yaml";
  if (!fs::exists(file)) {
    throw InputError(InputLocation(file),
                     "missing: --world-of needs a sequence written by "
                     "superdyna simulate");
  }
  const io::YamlFile yaml = io::YamlFile::load(file);
  if (!yaml.has("world_source")) {
    throw InputError(InputLocation(file, 0, "world_source"),
                     "missing (written by an older superdyna): regenerate the sequence");
  }
  const YAML::Node node = yaml.child("world_source");
  const auto text = [&](const std::string& key) {
    return yaml.scalar(yaml.child(node, key, "world_source." + key), "world_source." + key);
  };
  const auto number = [&](const std::string& key) {
    return yaml.number(yaml.child(node, key, "world_source." + key), "world_source." + key);
  };
  const auto path = [&](const std::string& key, const std::string& none) {
    const std::string value = text(key);
    return value == none ? std::nullopt : std::optional<fs::path>(value);
  };
  const auto integer = [&](const std::string& key) {
    const std::string value = text(key);
    try {
      std::size_t used = 0;
      const unsigned long long parsed = std::stoull(value, &used);
      if (used == value.size()) return static_cast<std::uint64_t>(parsed);
    } catch (const std::exception&) {
    }
    throw InputError(yaml.at(node[key], "world_source." + key),
                     "expected a non-negative integer, got '" + value + "'");
  };
  WorldSource source;
  source.sequence = sequence;
  source.motion.trajectory_file = path("trajectory", "procedural");
  source.motion.read.format = io::parseTrajectoryFormat(text("trajectory_format"));
  source.motion.read.kitti_times = path("trajectory_times", "none");
  if (text("segment") != "none") source.motion.read.segment = static_cast<int>(integer("segment"));
  source.motion.convention = parseMotionConvention(text("motion_convention"));
  source.motion.mount_height_m = number("mount_height_m");
  source.motion.start_s = number("start_s");
  source.motion.duration_s = number("duration_s");
  source.knot_spacing_s = number("knot_spacing_s");
  source.scene = parseSceneType(text("scene"));
  source.seed = integer("seed");
  source.texture_dir = path("texture_dir", "procedural");
  if (node["background_contrast"]) {
    source.background_contrast = number("background_contrast");
    if (!(source.background_contrast > 0.0 && source.background_contrast <= 1.0)) {
      throw InputError(
          yaml.at(node["background_contrast"], "world_source.background_contrast"),
          fmt::format("expected a number in (0, 1], got {}", source.background_contrast));
    }
  }
  if (node["texture_variety"]) {
    const std::uint64_t variety = integer("texture_variety");
    if (variety > 1000) {
      throw InputError(
          yaml.at(node["texture_variety"], "world_source.texture_variety"),
          fmt::format("expected an integer in [0, 1000], got '{}'", text("texture_variety")));
    }
    source.texture_variety = static_cast<int>(variety);
  }
  source.fingerprint = integer("static_world_fingerprint");
  return source;
}

}  // namespace superdyna::sim
