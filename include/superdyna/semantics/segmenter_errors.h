#pragma once
// Simulated segmenter errors (issue 51): any backend's output with the two errors a segmenter
// makes on real images, so that their cost can be measured with ground truth on simulated
// sequences in every sensor mode.
//
// - Missed detections: every real instance is removed from a frame with probability miss_rate,
//   drawn per (seed, t_ns, instance id): an object whose id names it in both images is missed in
//   both.
// - False objects: on average false_objects_per_frame blobs per frame, each an axis-aligned
//   ellipse on pixels that are background in the backend's segmentation (never over a real
//   instance, not even a missed one: a false object's pixels are static structure), with the
//   class vehicle (wider than tall, height 0.45-0.75 of the width) or pedestrian (taller than
//   wide, width 0.3-0.5 of the height), each with probability 1/2, and a longer side drawn
//   uniformly in [false_object_min_px, false_object_max_px]. Its centre is a background pixel
//   (up to 50 draws; a frame too crowded for one gets fewer). Its id is in
//   [kInjectedObjectIdBase, kInjectedObjectIdLast] (segmenter_error_options.h): over a backend
//   whose ids name objects an id drawn for each new false object (kept while it lives, never one
//   of a living false object; a dead one's id comes back with probability 1/32767 per birth),
//   otherwise numbered afresh in each frame as a network would. Its score is the
//   median score of the frame's real instances (1 without any), so it cannot be told apart.
// - Flicker / persistence: a false object lives false_object_frames frames, then vanishes. Births
//   per frame are Poisson(false_objects_per_frame / false_object_frames), so that the mean number
//   present is false_objects_per_frame; the first frame starts from that steady state (Poisson
//   many objects, each with a remaining life uniform in 1..false_object_frames). Between frames
//   an object follows the structure under it: its central patch (at most 64x64 px) of the last
//   left image is found again in the new one by normalised cross-correlation within 32 px; with
//   a weak match (< 0.6, e.g. textureless structure) it keeps its pixel position. An object whose
//   centre leaves the image vanishes early.
//
// Masks shifted per frame are not simulated here; the fixed dilation / erosion of every mask
// (mask_perturbation.h) runs before the errors when both are asked for.
//
// Determinism: every draw comes from a SplitMix64 stream seeded by (seed, t_ns, purpose), so the
// same seed and frame times give bit-identical masks on every platform. With
// false_object_frames == 1 a frame's masks depend only on (seed, t_ns, backend output); with
// persistence they also depend on the frames segmented before (the same in every run over the
// same frames). Camera 0 drives the state; camera 1 (the right image, segmented after the left
// one of the same t_ns) gets the left image's false objects at the same pixels, painted on its
// own background, and the same missed ids.

#include <memory>
#include <mutex>
#include <opencv2/core.hpp>
#include <vector>

#include "superdyna/semantics/segmenter.h"
#include "superdyna/semantics/segmenter_error_options.h"

namespace superdyna::semantics {

/// One injected false object as it is in the current frame.
struct FalseObject {
  int id = 0;
  int class_id = 0;      ///< sensors::kInstanceClassVehicle or kInstanceClassPedestrian.
  cv::Point2d centre;    ///< [px] in the left image.
  cv::Size2d half_axes;  ///< Ellipse half-width and half-height [px].
  int frames_left = 0;   ///< Frames it still lives, this one included.
};

/// Any segmenter with simulated errors. Not for concurrent use by several threads (a mutex
/// guards it; frames must come in time order for persistence to mean anything).
class ErrorInjectingSegmenter : public Segmenter {
 public:
  ErrorInjectingSegmenter(std::unique_ptr<Segmenter> segmenter,
                          const SegmenterErrorOptions& options);
  Segmentation segment(const cv::Mat& image, TimeNs t_ns, int camera) override;
  std::string description() const override;
  bool idsNameObjects() const override { return segmenter_->idsNameObjects(); }

  /// The false objects of the last left image segmented (for tests and logs).
  std::vector<FalseObject> falseObjects() const;

 private:
  /// Moves the living false objects to the left image `gray` of `t_ns`, ages them and adds the
  /// newborn on pixels that are 0 in `background` (the backend's ids).
  void advance(const cv::Mat& gray, const cv::Mat& background, TimeNs t_ns);
  /// Ages the objects and moves each with the structure under it from last_gray_ to `gray`.
  void trackObjects(const cv::Mat& gray);
  /// This frame's newborn false objects (the steady state's population on the first frame).
  void addBirths(const cv::Mat& background, TimeNs t_ns, bool first_frame);

  std::unique_ptr<Segmenter> segmenter_;
  SegmenterErrorOptions options_;
  mutable std::mutex mutex_;
  std::vector<FalseObject> objects_;  ///< Of the frame last_t_ns_.
  cv::Mat last_gray_;                 ///< The left image of last_t_ns_.
  TimeNs last_t_ns_ = 0;
  bool has_frame_ = false;
};

/// Removes the instances `miss_rate` draws for (seed, t_ns) from `segmentation` (cloning ids).
void removeMissedInstances(Segmentation& segmentation, const SegmenterErrorOptions& options,
                           TimeNs t_ns);

/// Paints `objects` onto the pixels that are 0 in `background_ids` and still 0 in
/// `segmentation.ids`, adds them as instances (score `score`) and updates boxes and areas.
void paintFalseObjects(Segmentation& segmentation, const cv::Mat& background_ids,
                       const std::vector<FalseObject>& objects, float score);

}  // namespace superdyna::semantics
