#include "core/lsm_image_store.h"

#include <stdexcept>

namespace flysfm {

bool LsmImageStore::Options::Check() const {
  return num_pyramid_levels >= 1 && cache_megabytes >= 0;
}

LsmImageStore::LsmImageStore(const Options& options) : options_(options) {
  if (!options_.Check()) throw std::invalid_argument("invalid LSM image store options");
}

void LsmImageStore::Add(image_t image_id, cv::Mat grey) {
  greys_[image_id] = std::move(grey);
}

std::vector<LsmImage> LsmImageStore::Pyramid(image_t image_id) {
  const auto it = pyramids_.find(image_id);
  if (it != pyramids_.end()) {
    recency_.splice(recency_.begin(), recency_, it->second.recency);
    return it->second.levels;
  }
  CachedPyramid pyramid;
  pyramid.levels = BuildLsmPyramid(greys_.at(image_id), options_.num_pyramid_levels);
  for (const LsmImage& level : pyramid.levels) pyramid.bytes += level.ByteSize();
  recency_.push_front(image_id);
  pyramid.recency = recency_.begin();
  cache_bytes_ += pyramid.bytes;
  std::vector<LsmImage> levels = pyramid.levels;
  pyramids_.emplace(image_id, std::move(pyramid));
  const std::size_t budget = std::size_t(options_.cache_megabytes) << 20;
  while (cache_bytes_ > budget && recency_.size() > 1) {
    const auto evicted = pyramids_.find(recency_.back());
    cache_bytes_ -= evicted->second.bytes;
    pyramids_.erase(evicted);
    recency_.pop_back();
  }
  return levels;
}

}  // namespace flysfm
