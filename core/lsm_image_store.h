#pragma once

// What LSM needs of the images it has seen, within a bounded memory whatever
// the length of the session (docs/engine.md, "Memory"):
// - an image LSM may still search (the new image; a waiting image, which may
//   register later with densification) is kept whole, in 8-bit grey with its
//   8-bit pyramid, and its LSM pyramid (spline coefficients) is built when
//   it is searched;
// - any other image only ever gives LSM templates, at its own 2D points:
//   refinement reads its keypoints' levels and level 0, densification every
//   level at its observations. Of such an image only 8-bit tiles covering windows
//   around its 2D points are kept, on every pyramid level, and a template is
//   cut from them when needed (an LsmImage with an origin).
// The tiles are kept within a byte budget, the least recently used image's
// dropped first; an image whose tiles were dropped takes no part in LSM any
// more (its pairs stay unrefined; it is no densification reference).

#include <cstddef>
#include <cstdint>
#include <functional>
#include <istream>
#include <list>
#include <memory>
#include <ostream>
#include <unordered_map>
#include <vector>

#include <Eigen/Core>
#include <opencv2/core.hpp>

#include "geometry/types.h"
#include "lsm/densify.h"
#include "lsm/lsm.h"

namespace flysfm {

class LsmImageStore {
 public:
  struct Options {
    // Pyramid levels kept per image (densification's coarse-to-fine levels;
    // DensifyOptions::num_pyramid_levels at the least).
    int num_pyramid_levels = 3;
    // Pixels kept around each 2D point of an older image on level 0: a
    // template's reach (LsmTemplateReach) plus the shift of densification's
    // shifted windows.
    int template_reach_px =
        LsmTemplateReach(LsmOptions()) + static_cast<int>(DensifyOptions().window_shift_px + 0.5);
    // The same on the coarser levels, where windows are not shifted.
    int coarse_template_reach_px = LsmTemplateReach(LsmOptions());
    // Budget of the tiles kept of older images. A photo's 1 500 keypoints
    // keep 3.2 MB on three levels at 6 MP, 6.2 MB at 24 MP
    // (bench/bench_photos): 768 MB keeps the templates of the last 240 or
    // 120 photos used, which retrieval's candidates mostly are, and leaves
    // a 24 MP session of 300 photos under 2 GB in all (docs/engine.md,
    // "Memory", with what less costs in accuracy).
    int window_budget_megabytes = 768;
    // Waiting images kept whole beyond the new one, the most recent first;
    // an older waiting image keeps only windows and, if it registers later,
    // registers without densification. Bounds the memory of a session that
    // cannot initialise or leaves many images waiting.
    int max_whole_waiting_images = 8;

    bool Check() const;
  };

  explicit LsmImageStore(const Options& options);

  // Keeps the image whole.
  void Add(image_t image_id, cv::Mat grey);
  // Keeps only the tiles covering windows around `points` (full-resolution
  // positions) and drops the whole image; the budget may then drop other
  // images' tiles.
  void KeepWindows(image_t image_id, const std::vector<Eigen::Vector2d>& points);

  bool IsWhole(image_t image_id) const;
  // Whether the image still gives LSM templates (whole, or its tiles kept).
  bool HasPixels(image_t image_id) const;
  // The whole images, in the order they were added.
  std::vector<image_t> WholeImages() const;

  // A whole image's LSM pyramid, to search in with cubic-spline LSM
  // (LsmImage::SplineOnly, from the 8-bit levels). The last one built is
  // kept: refinement and densification search the new image in one call.
  // Empty for an image kept as windows or whose pixels the budget dropped.
  std::vector<LsmImage> SearchPyramid(image_t image_id);
  // The window of pyramid `level` around the full-resolution `point`,
  // `reach` pixels of that level around the pixel nearest to it (cut at the
  // image's border); empty when the image no longer has those pixels.
  LsmImage Window(image_t image_id, int level, const Eigen::Vector2d& point, int reach);

  // Bytes held: tiles of older images, and whole images (8-bit pyramids
  // and the search pyramid).
  std::size_t window_bytes() const { return window_bytes_; }
  std::size_t whole_bytes() const;

  // The engine's checkpoint. An image's tiles never change once kept, so
  // they are written once, on their own (WriteWindows, for an image kept as
  // tiles); the state is which images are kept, in which order.
  void WriteWindows(image_t image_id, std::ostream& out) const;
  void WriteState(std::ostream& out) const;
  // Restores a written state into an empty store. `load_grey` gives an
  // image's grey pixels again (decoded from its file), `load_windows` an
  // image's written tiles. A whole image is loaded at once. An image kept
  // as tiles whose tiles were not written (its file holds them: the
  // checkpoint need not) gets them cut from `load_grey` around
  // `load_points` the first time LSM asks for a window: a restart decodes
  // no more than the next images' LSM reads. An image that gives neither
  // (empty, nullptr) is kept no more, as if the budget had dropped it.
  // Throws std::runtime_error on a truncated or inconsistent stream.
  using GreyLoader = std::function<cv::Mat(image_t)>;
  using WindowsLoader = std::function<std::unique_ptr<std::istream>(image_t)>;
  using PointsLoader = std::function<std::vector<Eigen::Vector2d>(image_t)>;
  void ReadState(std::istream& in, const GreyLoader& load_grey,
                 const WindowsLoader& load_windows, const PointsLoader& load_points);

 private:
  struct Level {
    int width = 0;
    int height = 0;
    cv::Mat whole;  // CV_8U, while the image is whole
    // Tiles of kTile x kTile pixels: tile (tx, ty) at tiles[offset[ty * tiles_x + tx]], or
    // none where the offset is -1.
    int tiles_x = 0;
    std::vector<std::int64_t> offsets;
    std::vector<std::uint8_t> tiles;
  };
  struct Entry {
    std::vector<Level> levels;
    std::uint64_t arrival = 0;
    bool whole = true;
    std::size_t bytes = 0;  // of the tiles
    std::list<image_t>::iterator recency;  // among images kept as tiles
    // Restored without its tiles: they are cut from these when first read.
    std::function<cv::Mat()> deferred_grey;
    std::vector<Eigen::Vector2d> deferred_points;
  };
  static constexpr int kTile = 16;

  // The 8-bit pyramid of `grey`, every level whole.
  std::vector<Level> BuildLevels(cv::Mat grey) const;
  // Keeps only the tiles of `entry`'s whole levels around `points`; sets
  // its bytes.
  void CutTiles(const std::vector<Eigen::Vector2d>& points, Entry* entry) const;
  // Drops the least recently used tiles while over the budget.
  void EnforceBudget();
  // Cuts a deferred entry's tiles; false (and the entry dropped) when its
  // pixels cannot be had.
  bool MaterializeDeferred(image_t image_id);
  // Cuts a window from the tiles; empty when one is missing.
  static cv::Mat CutFromTiles(const Level& level, const cv::Rect& rect);

  Options options_;
  std::unordered_map<image_t, Entry> entries_;
  std::uint64_t next_arrival_ = 0;
  std::list<image_t> recency_;  // most recently used first
  std::size_t window_bytes_ = 0;
  image_t search_image_id_ = kInvalidImageId;
  std::vector<LsmImage> search_pyramid_;
};

}  // namespace flysfm
