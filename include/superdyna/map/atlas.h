#pragma once
// The maps of a run that tracking has left (ORB-SLAM3's atlas). When a tracking failure outlasts
// relocalisation, the tracker starts a new map and hands the one it leaves to the atlas instead of
// dropping it; loop closing keeps recognising the atlas maps' places and, when the active map sees
// one of them again, merges that map into the active one (loop/loop_closer.h). Only maps that
// will not move as a whole any more are kept (visual maps; inertial ones once their inertial
// initialisation has run), so that a merge is a rigid transform (a similarity for visual
// monocular maps), and the ids of all of them are unique (map::Map's continuing counters).
//
// Thread-safe: the tracking thread adds maps, the loop thread reads them, the mapping thread takes
// the one it merges. A map handed out stays valid for its holder after it was taken; a map in the
// atlas is never changed until taken.

#include <cstddef>
#include <memory>
#include <mutex>
#include <vector>

#include "superdyna/map/map.h"

namespace superdyna::map {

class Atlas {
 public:
  /// Keeps `map` (ignored when null or empty).
  void add(std::shared_ptr<Map> map);
  /// The map holding keyframe `id`, nullptr when none does.
  std::shared_ptr<Map> mapOf(KeyFrameId id) const;
  /// Removes `map` and returns it; nullptr when it is not (any more) in the atlas.
  std::shared_ptr<Map> take(const Map* map);
  /// The keyframe ids of all maps, sorted.
  std::vector<KeyFrameId> keyFrameIds() const;
  std::size_t numMaps() const;
  std::size_t numKeyFrames() const;
  /// Forgets every map.
  void clear();

 private:
  mutable std::mutex mutex_;
  std::vector<std::shared_ptr<Map>> maps_;  ///< In the order they were left.
};

}  // namespace superdyna::map
