#pragma once

// What LSM needs of the images it has seen: each image's grey pixels and,
// built on demand, its LSM pyramid (refinement reads level 0, densification
// every level). Pyramids are kept, most recently used first, within a byte
// budget: a new image meets mostly recent ones.

#include <cstddef>
#include <list>
#include <unordered_map>
#include <vector>

#include <opencv2/core.hpp>

#include "geometry/types.h"
#include "lsm/lsm.h"

namespace flysfm {

class LsmImageStore {
 public:
  struct Options {
    // Pyramid levels built per image (densification's coarse-to-fine levels;
    // DensifyOptions::num_pyramid_levels at the least).
    int num_pyramid_levels = 3;
    // Budget of the cached pyramids; the grey images are not counted.
    int cache_megabytes = 512;

    bool Check() const;
  };

  explicit LsmImageStore(const Options& options);

  void Add(image_t image_id, cv::Mat grey);
  // The image's pyramid, built and cached on first use. The levels share
  // pixels with the cache (cv::Mat), so the copy is cheap and outlives an
  // eviction.
  std::vector<LsmImage> Pyramid(image_t image_id);

  std::size_t cache_bytes() const { return cache_bytes_; }

 private:
  struct CachedPyramid {
    std::vector<LsmImage> levels;
    std::list<image_t>::iterator recency;
    std::size_t bytes = 0;
  };

  Options options_;
  std::unordered_map<image_t, cv::Mat> greys_;
  std::unordered_map<image_t, CachedPyramid> pyramids_;
  std::list<image_t> recency_;  // most recently used first
  std::size_t cache_bytes_ = 0;
};

}  // namespace flysfm
