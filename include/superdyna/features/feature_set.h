#pragma once
// Keypoints and descriptors shared by every feature extractor of the front end: ORB (binary,
// 256-bit descriptors) now, learned extractors (XFeat, SuperPoint: float descriptors) later, and
// the interface they all implement.
//
// Pixel convention: the centre of the top-left pixel is (0, 0), x to the right, y down, as in
// CameraModel. Angles follow cv::KeyPoint: degrees in [0, 360), measured from the +x axis towards
// the +y axis (clockwise on screen).

#include <Eigen/Core>
#include <opencv2/core.hpp>
#include <string>
#include <vector>

namespace superdyna::features {

/// Semantic class ids a keypoint can carry (filled in by the dynamic-object stage).
inline constexpr int kClassBackground = 0;
inline constexpr int kClassVehicle = 1;
inline constexpr int kClassPedestrian = 2;
inline constexpr int kClassOtherMovable = 3;  ///< Animals and other movable things.

/// One detected keypoint, in level-0 (full resolution) image coordinates.
struct Keypoint {
  Eigen::Vector2d pixel = Eigen::Vector2d::Zero();  ///< Position in the level-0 image [px].
  float angle = -1.0f;    ///< Orientation [deg] in [0, 360); -1 when the extractor has none.
  int octave = 0;         ///< Pyramid level of detection (0 = full resolution).
  float response = 0.0f;  ///< Detector score, larger is stronger (ORB: FAST score).
  float size = 0.0f;      ///< Diameter of the described patch in level-0 pixels [px].
  int class_id = 0;  ///< kClassBackground / kClassVehicle / kClassPedestrian / kClassOtherMovable.
  int instance_id = 0;  ///< Object instance the keypoint lies on; 0 = static background.
  /// The mask holds another instance (or the background) within a few pixels: the corner may be
  /// formed with what lies behind the object's silhouette, so it moves with neither of them, and
  /// its stereo depth may belong to either (tracking::labelKeypoints).
  bool on_instance_border = false;
};

/// How descriptors are stored and compared.
enum class DescriptorType {
  kBinary,  ///< CV_8UC1 rows of bits (ORB: 32 bytes = 256 bits), compared by Hamming distance.
  kFloat,   ///< CV_32FC1 rows (learned descriptors), compared by Euclidean distance.
};
std::string toString(DescriptorType type);

/// The keypoints of one image and their descriptors (row i describes keypoints[i]).
struct FeatureSet {
  std::vector<Keypoint> keypoints;
  cv::Mat descriptors;  ///< keypoints.size() rows; type by descriptor_type.
  DescriptorType descriptor_type = DescriptorType::kBinary;
  cv::Size image_size;  ///< Size of the image the features come from [px].

  std::size_t size() const { return keypoints.size(); }
  bool empty() const { return keypoints.empty(); }
  /// Descriptor length: bytes for kBinary, floats for kFloat (0 when there are no descriptors).
  int descriptorLength() const { return descriptors.cols; }
  /// Throws InputError when descriptor rows and keypoints disagree in number or the matrix type
  /// does not fit descriptor_type.
  void validate() const;
  /// The features with the given indices, in that order (indices must be valid).
  FeatureSet select(const std::vector<int>& indices) const;
};

/// A keypoint detector + descriptor. Implementations must be deterministic: the same image gives
/// the same FeatureSet. extract() is not const so implementations may keep scratch buffers; use
/// one extractor per thread.
class FeatureExtractor {
 public:
  virtual ~FeatureExtractor() = default;
  /// Features of an 8-bit grayscale image (CV_8UC1). Throws InputError for other image types.
  virtual FeatureSet extract(const cv::Mat& gray) = 0;
  /// Short name, e.g. "orb".
  virtual std::string name() const = 0;
};

}  // namespace superdyna::features
