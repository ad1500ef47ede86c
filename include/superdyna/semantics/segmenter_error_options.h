#pragma once
// Options of the simulated segmenter errors (segmenter_errors.h) and the id range of the false
// objects they inject. Kept apart from the wrapper so that SegmenterOptions and the evaluation
// (eval/dynamic_decisions.h) can name them without the segmenters.

#include <cstdint>

namespace superdyna::semantics {

/// Injected false objects have instance ids from here up (to 0xFFFE); a backend whose ids reach
/// this range cannot be combined with false objects (ErrorInjectingSegmenter throws). The
/// simulator numbers its agents from 1, so ground-truth ids never reach it: `superdyna
/// eval-dynamic` scores a logged object with such an id that the ground truth does not list as a
/// static object (its features lie on static structure). The moving-object test must not look at
/// the range: to it a false object is an object like any other.
inline constexpr int kInjectedObjectIdBase = 0x8000;  // 32768
inline constexpr int kInjectedObjectIdLast = 0xFFFE;

/// A segmenter's typical errors, injected into any backend's output (semantics.error_*). All
/// draws are seeded from `seed` and the frame time, so a run stays bit-identical.
struct SegmenterErrorOptions {
  /// Mean number of false objects (vehicle or pedestrian blobs on background pixels) present in a
  /// frame; the number born in a frame is Poisson distributed. 0 = none.
  double false_objects_per_frame = 0.0;
  /// Frames a false object lives, following the structure it lies on, before it vanishes
  /// (1 = a fresh set of false objects every frame; > 1 = the persistent misdetection of one
  /// static structure, e.g. a building front taken for a vehicle).
  int false_object_frames = 1;
  /// Range of a false object's longer side [px] (uniformly drawn).
  int false_object_min_px = 40;
  int false_object_max_px = 160;
  /// Probability that a real instance is missing from a frame (drawn per instance and frame).
  double miss_rate = 0.0;
  /// Seed of every draw; runs with the same seed inject the same errors.
  int seed = 0;

  /// Whether any error is asked for.
  bool enabled() const { return false_objects_per_frame > 0.0 || miss_rate > 0.0; }
  void validate() const;  ///< OptionError naming the key (semantics.error_*).
  bool operator==(const SegmenterErrorOptions&) const = default;
};

}  // namespace superdyna::semantics
