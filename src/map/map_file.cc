#include "superdyna/map/map_file.h"

#include <fmt/format.h>

#include <algorithm>
#include <array>
#include <boost/crc.hpp>
#include <cereal/archives/portable_binary.hpp>
#include <cereal/types/map.hpp>
#include <cereal/types/optional.hpp>
#include <cereal/types/string.hpp>
#include <cereal/types/tuple.hpp>
#include <cereal/types/vector.hpp>
#include <cmath>
#include <fstream>
#include <iterator>
#include <sstream>
#include <tuple>
#include <type_traits>

#include "superdyna/core/atomic_file.h"
#include "superdyna/core/error.h"

// cereal finds these by argument-dependent lookup through its archive types.
namespace cereal {

/// Elements of a vector or characters of a string read at a time (see the loads below).
inline constexpr size_type kLoadChunk = 4096;

/// Vectors are written as cereal writes them (length, then the elements), but read as they
/// arrive: cereal's own load resizes to the stored length first, so a damaged or crafted length
/// (found by fuzz/map_file_fuzzer.cc) allocated up to the whole address space before the payload
/// ran out. Growing with the elements read bounds the memory by the payload's size.
template <class T>
void load(PortableBinaryInputArchive& ar, std::vector<T>& vector) {
  size_type size = 0;
  ar(make_size_tag(size));
  vector.clear();
  if constexpr (std::is_arithmetic_v<T> && !std::is_same_v<T, bool>) {
    while (vector.size() < size) {
      const std::size_t first = vector.size();
      const std::size_t count = std::min<size_type>(size - first, kLoadChunk);
      vector.resize(first + count);
      ar(binary_data(vector.data() + first, count * sizeof(T)));
    }
  } else {
    for (size_type i = 0; i < size; ++i)
      ar(vector.emplace_back());
  }
}

/// Booleans (MapPoint::bad, whether an optional holds a value) are one byte, 0 or 1; cereal copies
/// the byte into the bool, and any other value (found by fuzz/map_file_fuzzer.cc) made a bool of
/// no valid value (undefined behaviour) instead of an error.
inline void load(PortableBinaryInputArchive& ar, bool& value) {
  std::uint8_t byte = 0;
  ar(byte);
  if (byte > 1) throw superdyna::InputError(fmt::format("boolean stored as byte {}", byte));
  value = byte == 1;
}

/// Strings likewise: the characters are read in chunks, not into a buffer of the stored length.
inline void load(PortableBinaryInputArchive& ar, std::string& text) {
  size_type size = 0;
  ar(make_size_tag(size));
  text.clear();
  while (text.size() < size) {
    const std::size_t first = text.size();
    const std::size_t count = std::min<size_type>(size - first, kLoadChunk);
    text.resize(first + count);
    ar(binary_data(text.data() + first, count));
  }
}

template <class Archive>
void serialize(Archive& ar, Eigen::Vector2d& v) {
  ar(v.x(), v.y());
}

template <class Archive>
void serialize(Archive& ar, Eigen::Vector3d& v) {
  ar(v.x(), v.y(), v.z());
}

template <class Archive>
void serialize(Archive& ar, superdyna::SE3d& T) {
  ar(T.q.w(), T.q.x(), T.q.y(), T.q.z(), T.t);
}

/// Descriptor matrices: type (-1 = empty), rows, columns, then the elements row by row.
template <class Archive>
void save(Archive& ar, const cv::Mat& m) {
  const int type = m.empty() ? -1 : m.type();
  ar(type, m.rows, m.cols);
  if (m.empty()) return;
  const cv::Mat c = m.isContinuous() ? m : m.clone();
  if (type == CV_32FC1) {
    ar(std::vector<float>(c.ptr<float>(), c.ptr<float>() + c.total()));
  } else {
    ar(std::vector<std::uint8_t>(c.ptr<std::uint8_t>(), c.ptr<std::uint8_t>() + c.total()));
  }
}

template <class Archive>
void load(Archive& ar, cv::Mat& m) {
  int type = -1, rows = 0, cols = 0;
  ar(type, rows, cols);
  if (type == -1) {
    m = cv::Mat();
    return;
  }
  if ((type != CV_8UC1 && type != CV_32FC1) || rows <= 0 || cols <= 0 || cols > 4096)
    throw superdyna::InputError(
        fmt::format("descriptor matrix of type {} with {} x {} elements", type, rows, cols));
  const auto fill = [&](auto elements) {
    ar(elements);
    if (elements.size() != static_cast<std::size_t>(rows) * static_cast<std::size_t>(cols))
      throw superdyna::InputError(fmt::format("descriptor matrix of {} x {} holds {} elements",
                                              rows, cols, elements.size()));
    m = cv::Mat(rows, cols, type);
    std::copy(elements.begin(), elements.end(), m.ptr<typename decltype(elements)::value_type>());
  };
  if (type == CV_32FC1) {
    fill(std::vector<float>());
  } else {
    fill(std::vector<std::uint8_t>());
  }
}

template <class Archive>
void serialize(Archive& ar, superdyna::sensors::ImuSample& s) {
  ar(s.t_ns, s.gyro, s.accel);
}

template <class Archive>
void serialize(Archive& ar, superdyna::sensors::CameraCalibration& c) {
  ar(c.name, c.T_b_c, c.width, c.height, c.rate_hz, c.model, c.fx, c.fy, c.cx, c.cy,
     c.distortion_model, c.distortion);
}

template <class Archive>
void serialize(Archive& ar, superdyna::map::KeyFrameKeypoint& k) {
  ar(k.pixel, k.normalized, k.octave, k.angle, k.camera, k.class_id, k.instance_id, k.right_x,
     k.depth_m);
}

template <class Archive>
void serialize(Archive& ar, superdyna::map::KeyFrame& kf) {
  ar(kf.id, kf.t_ns, kf.T_w_b, kf.v_w, kf.bg, kf.ba, kf.previous, kf.imu_from_previous,
     kf.keypoints, kf.descriptors, kf.map_points);
}

template <class Archive>
void serialize(Archive& ar, superdyna::map::MapPoint& p) {
  ar(p.id, p.p_w, p.descriptor, p.observations, p.class_id, p.instance_id, p.normal_w,
     p.min_distance_m, p.max_distance_m, p.bad, p.visible_count, p.found_count);
}

template <class Archive>
void serialize(Archive& ar, superdyna::map::MapContents& c) {
  ar(c.keyframes, c.points, c.next_keyframe_id, c.next_point_id);
}

template <class Archive>
void serialize(Archive& ar, superdyna::map::MapOptions& o) {
  ar(o.T_b_c, o.scale_factor, o.num_levels);
}

template <class Archive>
void serialize(Archive& ar, superdyna::map::MapIdentity& id) {
  ar(id.feature_type, id.descriptor_type, id.descriptor_columns, id.sensor_mode, id.cameras,
     id.T_b_i);
}

template <class Archive>
void serialize(Archive& ar, superdyna::map::MapFile& f) {
  ar(f.identity, f.options, f.contents, f.right, f.covisibility, f.inertial_stages);
}

}  // namespace cereal

namespace superdyna::map {

namespace fs = std::filesystem;

namespace {

constexpr char kMagic[8] = {'S', 'D', 'Y', 'N', 'A', 'M', 'A', 'P'};

/// What follows the magic, written by cereal.
struct Header {
  std::uint32_t version = kMapFormatVersion;
  MapDescriptorType descriptor_type = MapDescriptorType::kNone;
  std::uint64_t payload_bytes = 0;
  std::uint32_t checksum = 0;

  template <class Archive>
  void serialize(Archive& ar) {
    ar(version, descriptor_type, payload_bytes, checksum);
  }
};

/// Magic, cereal's endianness byte, version, descriptor type, payload size, checksum.
constexpr std::size_t kHeaderBytes = sizeof(kMagic) + 1 + 4 + 1 + 8 + 4;

std::uint32_t crc32(const std::string& bytes) {
  boost::crc_32_type crc;
  crc.process_bytes(bytes.data(), bytes.size());
  return crc.checksum();
}

InputError fileError(const fs::path& name, const std::string& what) {
  return InputError(InputLocation(name), "map file: " + what);
}

std::string describe(MapDescriptorType type) {
  return fmt::format("{} ({})", static_cast<int>(type), toString(type));
}

bool finite(const SE3d& T) {
  return T.q.coeffs().allFinite() && T.t.allFinite();
}

/// Values cereal cannot judge: descriptor types, finite states, the right observations' keys.
void checkValues(const MapFile& file, MapDescriptorType header_type, const fs::path& name) {
  if (file.identity.descriptor_type != header_type)
    throw fileError(name,
                    fmt::format("the header names descriptor type {}, the payload {}",
                                describe(header_type), describe(file.identity.descriptor_type)));
  const int expected_type = header_type == MapDescriptorType::kFloat ? CV_32FC1 : CV_8UC1;
  const auto checkDescriptors = [&](const cv::Mat& m, const std::string& what) {
    if (m.empty()) return;
    if (header_type == MapDescriptorType::kNone || m.type() != expected_type ||
        m.cols != file.identity.descriptor_columns)
      throw fileError(name, fmt::format("{}: descriptors of type {} with {} columns, the map's are "
                                        "{} with {}",
                                        what, m.type(), m.cols, toString(header_type),
                                        file.identity.descriptor_columns));
  };
  for (const KeyFrame& kf : file.contents.keyframes) {
    const std::string what = fmt::format("keyframe {}", kf.id);
    checkDescriptors(kf.descriptors, what);
    if (!finite(kf.T_w_b) || !kf.v_w.allFinite() || !kf.bg.allFinite() || !kf.ba.allFinite())
      throw fileError(name, what + ": a pose, velocity or bias is not finite");
  }
  for (const MapPoint& p : file.contents.points) {
    const std::string what = fmt::format("map point {}", p.id);
    checkDescriptors(p.descriptor, what);
    if (!p.descriptor.empty() && p.descriptor.rows != 1)
      throw fileError(name,
                      what + ": descriptor of " + std::to_string(p.descriptor.rows) + " rows");
    if (!p.p_w.allFinite()) throw fileError(name, what + ": position is not finite");
  }
  for (const auto& [id, right] : file.right) {
    const auto kf = std::find_if(file.contents.keyframes.begin(), file.contents.keyframes.end(),
                                 [id = id](const KeyFrame& k) { return k.id == id; });
    if (kf == file.contents.keyframes.end() || kf->keypoints.size() != right.size())
      throw fileError(name, fmt::format("right observations of keyframe {} match no keyframe's "
                                        "keypoints",
                                        id));
  }
  if (file.inertial_stages < 0 || file.inertial_stages > 3)
    throw fileError(name, fmt::format("inertial stages {} outside [0, 3]", file.inertial_stages));
}

std::vector<std::tuple<KeyFrameId, KeyFrameId, int>> covisibilityOf(const Map& map) {
  std::vector<std::tuple<KeyFrameId, KeyFrameId, int>> edges;
  for (const KeyFrameId a : map.keyFrameIds()) {
    for (const CovisibleKeyFrame& b : map.covisibleKeyFrames(a))
      if (b.id > a) edges.emplace_back(a, b.id, b.weight);
  }
  std::sort(edges.begin(), edges.end());
  return edges;
}

bool near(double a, double b) {
  return std::abs(a - b) <= 1e-6 * std::max(1.0, std::abs(a));
}

/// "<field>: the map's <a>, this run's <b>".
template <typename T>
std::string fieldDifference(const std::string& field, const T& saved, const T& current) {
  return fmt::format("{}: the map's {}, this run's {}", field, saved, current);
}

std::string formatTranslation(const Eigen::Vector3d& t) {
  return fmt::format("({}, {}, {}) m", t.x(), t.y(), t.z());
}

/// The first difference of two poses in the body frame ("" when equal within 1e-6 m and rad):
/// the translation with both values, or the angle between the rotations.
std::string poseDifference(const std::string& name, const SE3d& saved, const SE3d& current) {
  if ((saved.t - current.t).norm() > 1e-6)
    return fieldDifference(name + " translation", formatTranslation(saved.t),
                           formatTranslation(current.t));
  const double angle = rotationAngle((saved.inverse() * current).rotation());
  if (angle > 1e-6)
    return fmt::format("{} rotation: this run's is turned {:.6g} deg from the map's", name,
                       angle * 180.0 / M_PI);
  return "";
}

/// Name of distortion coefficient `i`: k1 k2 p1 p2 k3 (radial-tangential), k1..k4 (equidistant).
std::string coefficientName(DistortionModel model, std::size_t i) {
  if (model == DistortionModel::kRadialTangential) {
    constexpr std::array<const char*, 5> kNames = {"k1", "k2", "p1", "p2", "k3"};
    if (i < kNames.size()) return kNames[i];
  }
  return fmt::format("k{}", i + 1);
}

/// The first field in which two calibrations differ, named with both values ("" when none does).
std::string cameraDifference(const sensors::CameraCalibration& a,
                             const sensors::CameraCalibration& b) {
  if (a.width != b.width || a.height != b.height)
    return fieldDifference("resolution", fmt::format("{}x{}", a.width, a.height),
                           fmt::format("{}x{}", b.width, b.height));
  const std::array<std::tuple<const char*, double, double>, 4> intrinsics = {
      {{"fx", a.fx, b.fx}, {"fy", a.fy, b.fy}, {"cx", a.cx, b.cx}, {"cy", a.cy, b.cy}}};
  for (const auto& [field, saved, current] : intrinsics)
    if (!near(saved, current)) return fieldDifference(field, saved, current);
  if (a.distortion_model != b.distortion_model)
    return fieldDifference("distortion model", toString(a.distortion_model),
                           toString(b.distortion_model));
  if (a.distortion.size() != b.distortion.size())
    return fieldDifference("distortion coefficients", a.distortion.size(), b.distortion.size());
  for (std::size_t i = 0; i < a.distortion.size(); ++i) {
    if (!near(a.distortion[i], b.distortion[i]))
      return fieldDifference("distortion " + coefficientName(a.distortion_model, i),
                             a.distortion[i], b.distortion[i]);
  }
  return poseDifference("pose in the body (T_b_c)", a.T_b_c, b.T_b_c);
}

}  // namespace

std::string toString(MapDescriptorType type) {
  switch (type) {
    case MapDescriptorType::kNone:
      return "none";
    case MapDescriptorType::kBinary:
      return "binary";
    case MapDescriptorType::kFloat:
      return "float";
  }
  return "unknown";
}

MapFile makeMapFile(const Map& map, MapIdentity identity,
                    std::map<KeyFrameId, RightKeypoints> right, int inertial_stages) {
  MapFile file;
  file.identity = std::move(identity);
  file.options = map.options();
  file.contents = map.contents();
  for (const KeyFrame& kf : file.contents.keyframes) {
    const auto it = right.find(kf.id);
    if (it != right.end() && it->second.size() == kf.keypoints.size())
      file.right.emplace(kf.id, it->second);
  }
  file.covisibility = covisibilityOf(map);
  file.inertial_stages = inertial_stages;
  return file;
}

std::string serializeMapFile(const MapFile& file) {
  std::ostringstream payload_stream;
  {
    cereal::PortableBinaryOutputArchive archive(payload_stream);
    archive(file);
  }
  const std::string payload = payload_stream.str();
  std::ostringstream out;
  out.write(kMagic, sizeof(kMagic));
  {
    cereal::PortableBinaryOutputArchive archive(out);
    Header header{kMapFormatVersion, file.identity.descriptor_type, payload.size(), crc32(payload)};
    archive(header);
  }
  out << payload;
  return out.str();
}

MapFile parseMapFile(const std::string& bytes, const fs::path& name) {
  if (bytes.size() < kHeaderBytes)
    throw fileError(name, fmt::format("truncated: {} bytes, the header alone has {}", bytes.size(),
                                      kHeaderBytes));
  if (!std::equal(std::begin(kMagic), std::end(kMagic), bytes.begin()))
    throw fileError(name, "not a SuperDynaSLAM map file (no 'SDYNAMAP' magic at its start)");
  Header header;
  try {
    std::istringstream in(bytes.substr(sizeof(kMagic), kHeaderBytes - sizeof(kMagic)));
    cereal::PortableBinaryInputArchive archive(in);
    archive(header);
  } catch (const std::exception& e) {
    throw fileError(name, std::string("unreadable header: ") + e.what());
  }
  if (header.version != kMapFormatVersion)
    throw fileError(name, fmt::format("format version {}; this build reads version {}",
                                      header.version, kMapFormatVersion));
  if (static_cast<int>(header.descriptor_type) > 2)
    throw fileError(name, fmt::format("unknown descriptor type {} in the header",
                                      static_cast<int>(header.descriptor_type)));
  const std::size_t available = bytes.size() - kHeaderBytes;
  if (header.payload_bytes != available)
    throw fileError(name, fmt::format("{}: the header announces {} payload bytes, the file has {}",
                                      header.payload_bytes > available ? "truncated" : "corrupted",
                                      header.payload_bytes, available));
  const std::string payload = bytes.substr(kHeaderBytes);
  if (crc32(payload) != header.checksum)
    throw fileError(name, "corrupted: the payload's CRC-32 does not match the header's");
  MapFile file;
  try {
    std::istringstream in(payload);
    cereal::PortableBinaryInputArchive archive(in);
    archive(file);
    if (in.peek() != std::char_traits<char>::eof())
      throw std::runtime_error("bytes left after the map");
  } catch (const InputError& e) {
    throw fileError(name, std::string("corrupted payload: ") + e.what());
  } catch (const std::exception& e) {
    throw fileError(name, std::string("corrupted payload: ") + e.what());
  }
  checkValues(file, header.descriptor_type, name);
  std::unique_ptr<Map> map;
  try {
    map = Map::fromContents(file.options, file.contents);
  } catch (const std::exception& e) {
    throw fileError(name, std::string("inconsistent map: ") + e.what());
  }
  if (covisibilityOf(*map) != file.covisibility)
    throw fileError(name,
                    "inconsistent map: the stored covisibility graph differs from the one "
                    "its observations give");
  return file;
}

void writeMapFile(const fs::path& path, const MapFile& file) {
  writeFileAtomically(path, serializeMapFile(file));
}

MapFile readMapFile(const fs::path& path) {
  std::ifstream in(path, std::ios::binary);
  if (!in) throw fileError(path, "cannot open it");
  const std::string bytes((std::istreambuf_iterator<char>(in)), std::istreambuf_iterator<char>());
  if (in.bad()) throw fileError(path, "cannot read it");
  return parseMapFile(bytes, path);
}

std::unique_ptr<Map> buildMap(const MapFile& file) {
  return Map::fromContents(file.options, file.contents);
}

std::string identityMismatch(const MapIdentity& saved, const MapIdentity& current) {
  if (saved.feature_type != current.feature_type)
    return fmt::format("the map was made with {} features, this run uses {}", saved.feature_type,
                       current.feature_type);
  if (current.descriptor_type != MapDescriptorType::kNone &&
      (saved.descriptor_type != current.descriptor_type ||
       saved.descriptor_columns != current.descriptor_columns))
    return fmt::format("the map's descriptors are {} with {} columns, this run's {} with {}",
                       toString(saved.descriptor_type), saved.descriptor_columns,
                       toString(current.descriptor_type), current.descriptor_columns);
  if (saved.sensor_mode != current.sensor_mode)
    return fmt::format("the map was made in {} mode, this run is {}", saved.sensor_mode,
                       current.sensor_mode);
  if (saved.cameras.size() != current.cameras.size())
    return fmt::format("the map's rig has {} cameras, this run's {}", saved.cameras.size(),
                       current.cameras.size());
  for (std::size_t i = 0; i < saved.cameras.size(); ++i) {
    const std::string difference = cameraDifference(saved.cameras[i], current.cameras[i]);
    if (!difference.empty()) return fmt::format("camera {} differs in {}", i, difference);
  }
  if (saved.T_b_i.has_value() != current.T_b_i.has_value())
    return fmt::format("the map {} an IMU, this run {}", saved.T_b_i ? "has" : "has no",
                       current.T_b_i ? "has one" : "has none");
  if (saved.T_b_i) {
    const std::string difference =
        poseDifference("pose in the body (T_b_i)", *saved.T_b_i, *current.T_b_i);
    if (!difference.empty()) return "the IMU differs in " + difference;
  }
  return "";
}

}  // namespace superdyna::map
