#include "superdyna/map/atlas.h"

#include <algorithm>

namespace superdyna::map {

void Atlas::add(std::shared_ptr<Map> map) {
  if (!map || map->numKeyFrames() == 0) return;
  const std::lock_guard lock(mutex_);
  maps_.push_back(std::move(map));
}

std::shared_ptr<Map> Atlas::mapOf(KeyFrameId id) const {
  const std::lock_guard lock(mutex_);
  for (const std::shared_ptr<Map>& map : maps_)
    if (map->hasKeyFrame(id)) return map;
  return nullptr;
}

std::shared_ptr<Map> Atlas::take(const Map* map) {
  const std::lock_guard lock(mutex_);
  const auto it = std::find_if(maps_.begin(), maps_.end(),
                               [map](const std::shared_ptr<Map>& m) { return m.get() == map; });
  if (it == maps_.end()) return nullptr;
  std::shared_ptr<Map> taken = std::move(*it);
  maps_.erase(it);
  return taken;
}

std::vector<KeyFrameId> Atlas::keyFrameIds() const {
  std::vector<KeyFrameId> ids;
  const std::lock_guard lock(mutex_);
  for (const std::shared_ptr<Map>& map : maps_) {
    const std::vector<KeyFrameId> own = map->keyFrameIds();
    ids.insert(ids.end(), own.begin(), own.end());
  }
  std::sort(ids.begin(), ids.end());
  return ids;
}

std::size_t Atlas::numMaps() const {
  const std::lock_guard lock(mutex_);
  return maps_.size();
}

std::size_t Atlas::numKeyFrames() const {
  std::size_t count = 0;
  const std::lock_guard lock(mutex_);
  for (const std::shared_ptr<Map>& map : maps_)
    count += map->numKeyFrames();
  return count;
}

void Atlas::clear() {
  const std::lock_guard lock(mutex_);
  maps_.clear();
}

}  // namespace superdyna::map
