#pragma once
// Map files: a map saved at the end of one run (`superdyna run --save-map`) and loaded by another
// (`--load-map`), written with cereal's portable binary archives (little-endian, fixed-size
// integers), not a format of our own.
//
// Layout: a fixed-size header, then the payload.
//   header:  magic "SDYNAMAP" (8 bytes), format version (uint32), descriptor type (uint8:
//            0 none, 1 binary, 2 float), payload size (uint64), CRC-32 of the payload (uint32)
//   payload: the identity of what made the map (feature type, descriptor size, sensor mode, the
//            rig's camera calibrations and IMU extrinsics), the map options, every keyframe (id,
//            time, pose, velocity, biases, predecessor, IMU samples since the predecessor - what
//            its preintegration is rebuilt from -, keypoints with their classes and stereo
//            depth, descriptors, map point slots, right-camera observations), every map point
//            (position, descriptor, observations, class, viewing geometry, counters), the
//            covisibility graph, the inertial state of the world (inertial stages applied: 0 = not
//            gravity-aligned).
// The place-recognition database is not stored: it is rebuilt from the keyframes' descriptors.
//
// Reading checks, in order, and throws InputError naming the file and what is wrong: size of the
// header (truncated), magic (not a map file), version (another format version), payload size
// (truncated), checksum (corrupted), the payload's own structure (cereal), the values (descriptor
// types, matrix sizes, finite poses), the map's consistency (Map::fromContents) and that the
// stored covisibility equals the one the observations give. A damaged file never crashes.
//
// The same contents always serialise to the same bytes: save -> load -> save is byte-identical.

#include <cstdint>
#include <filesystem>
#include <map>
#include <memory>
#include <optional>
#include <string>
#include <vector>

#include "superdyna/map/map.h"
#include "superdyna/sensors/calibration.h"

namespace superdyna::map {

inline constexpr std::uint32_t kMapFormatVersion = 1;

/// Descriptor rows of the map's keyframes and points.
enum class MapDescriptorType : std::uint8_t { kNone = 0, kBinary = 1, kFloat = 2 };
std::string toString(MapDescriptorType type);

/// What made the map; a map is only used with the same features and rig.
struct MapIdentity {
  std::string feature_type;  ///< "orb" | "xfeat" | "superpoint" | "alike".
  MapDescriptorType descriptor_type = MapDescriptorType::kNone;
  int descriptor_columns = 0;  ///< Bytes (binary) or floats per row.
  std::string sensor_mode;     ///< "stereo" | "stereo-inertial" | "mono" | "mono-inertial".
  std::vector<sensors::CameraCalibration> cameras;  ///< cam0 [, cam1] (name, rate unused).
  std::optional<SE3d> T_b_i;                        ///< The IMU's pose in the body, when inertial.
};

/// Right-camera observations of a keyframe's keypoints (mapping::RightObservations).
using RightKeypoints = std::vector<std::optional<Eigen::Vector2d>>;

struct MapFile {
  MapIdentity identity;
  MapOptions options;
  MapContents contents;
  std::map<KeyFrameId, RightKeypoints> right;
  /// Covisibility edges (a < b, weight): written from the map, checked against it on reading.
  std::vector<std::tuple<KeyFrameId, KeyFrameId, int>> covisibility;
  /// Inertial (re-)initialisations applied to the map (0: not gravity-aligned, no IMU states).
  int inertial_stages = 0;
};

/// The map's contents and covisibility with the given identity and state.
MapFile makeMapFile(const Map& map, MapIdentity identity,
                    std::map<KeyFrameId, RightKeypoints> right, int inertial_stages);

/// The file's bytes (header and payload).
std::string serializeMapFile(const MapFile& file);
/// Parses bytes read from `name` (used in the messages); InputError as described above.
MapFile parseMapFile(const std::string& bytes, const std::filesystem::path& name);

/// Writes through core::AtomicFile (never half-written); InputError when it cannot.
void writeMapFile(const std::filesystem::path& path, const MapFile& file);
/// Reads and checks a map file; InputError naming the file and the problem.
MapFile readMapFile(const std::filesystem::path& path);

/// The map of a checked file (its consistency was checked when parsing).
std::unique_ptr<Map> buildMap(const MapFile& file);

/// Empty when `current` can use a map made with `saved`, else what differs (feature type,
/// descriptors - unless current's type is kNone, unknown -, sensor mode, a camera's calibration
/// or pose, the IMU's pose), in words.
std::string identityMismatch(const MapIdentity& saved, const MapIdentity& current);

}  // namespace superdyna::map
