#include "core/lsm_image_store.h"

#include <algorithm>
#include <cmath>
#include <cstring>
#include <stdexcept>

#include <opencv2/imgproc.hpp>

#include "geometry/binary_io.h"
#include "geometry/check.h"

namespace flysfm {
namespace {

// The pixels of `level` within `reach` of the pixel nearest to the
// full-resolution `point`, cut at the image's border.
cv::Rect WindowRect(int level, const Eigen::Vector2d& point, int reach, int width,
                    int height) {
  const double scale = 1.0 / (1 << level);
  const double x = std::round(scale * point.x());
  const double y = std::round(scale * point.y());
  if (!(std::abs(x) < 1e9 && std::abs(y) < 1e9)) return {};
  const int x0 = std::max(0, int(x) - reach);
  const int y0 = std::max(0, int(y) - reach);
  const int x1 = std::min(width - 1, int(x) + reach);
  const int y1 = std::min(height - 1, int(y) + reach);
  if (x1 < x0 || y1 < y0) return {};
  return {x0, y0, x1 - x0 + 1, y1 - y0 + 1};
}

}  // namespace

bool LsmImageStore::Options::Check() const {
  return num_pyramid_levels >= 1 && num_pyramid_levels <= 8 && template_reach_px >= 1 &&
         coarse_template_reach_px >= 1 && window_budget_megabytes >= 0 &&
         max_whole_waiting_images >= 0;
}

LsmImageStore::LsmImageStore(const Options& options) : options_(options) {
  if (!options_.Check()) throw std::invalid_argument("invalid LSM image store options");
}

std::vector<LsmImageStore::Level> LsmImageStore::BuildLevels(cv::Mat grey) const {
  std::vector<Level> levels(options_.num_pyramid_levels);
  levels[0].whole = std::move(grey);
  for (int l = 0; l < options_.num_pyramid_levels; ++l) {
    Level& level = levels[l];
    if (l > 0) cv::pyrDown(levels[l - 1].whole, level.whole);
    level.width = level.whole.cols;
    level.height = level.whole.rows;
  }
  return levels;
}

void LsmImageStore::Add(image_t image_id, cv::Mat grey) {
  Entry entry;
  entry.arrival = next_arrival_++;
  entry.levels = BuildLevels(std::move(grey));
  entries_[image_id] = std::move(entry);
}

void LsmImageStore::CutTiles(const std::vector<Eigen::Vector2d>& points, Entry* entry) const {
  entry->bytes = 0;
  for (int l = 0; l < int(entry->levels.size()); ++l) {
    Level& level = entry->levels[l];
    const int reach = l == 0 ? options_.template_reach_px : options_.coarse_template_reach_px;
    level.tiles_x = (level.width + kTile - 1) / kTile;
    const int tiles_y = (level.height + kTile - 1) / kTile;
    level.offsets.assign(std::size_t(level.tiles_x) * tiles_y, -1);
    std::int64_t num_tiles = 0;
    for (const Eigen::Vector2d& point : points) {
      const cv::Rect rect = WindowRect(l, point, reach, level.width, level.height);
      if (rect.empty()) continue;
      for (int ty = rect.y / kTile; ty <= (rect.y + rect.height - 1) / kTile; ++ty) {
        for (int tx = rect.x / kTile; tx <= (rect.x + rect.width - 1) / kTile; ++tx) {
          std::int64_t& offset = level.offsets[std::size_t(ty) * level.tiles_x + tx];
          if (offset < 0) offset = kTile * kTile * num_tiles++;
        }
      }
    }
    // Tiles at the right and bottom borders are padded; the padding is never
    // read (windows are cut at the border).
    level.tiles.assign(std::size_t(num_tiles) * kTile * kTile, 0);
    for (int ty = 0; ty < tiles_y; ++ty) {
      for (int tx = 0; tx < level.tiles_x; ++tx) {
        const std::int64_t offset = level.offsets[std::size_t(ty) * level.tiles_x + tx];
        if (offset < 0) continue;
        const int cols = std::min(kTile, level.width - tx * kTile);
        const int rows = std::min(kTile, level.height - ty * kTile);
        for (int r = 0; r < rows; ++r) {
          std::memcpy(&level.tiles[offset + r * kTile],
                      level.whole.ptr<std::uint8_t>(ty * kTile + r) + tx * kTile, cols);
        }
      }
    }
    level.whole.release();
    entry->bytes += level.tiles.size() + level.offsets.size() * sizeof(std::int64_t);
  }
  entry->whole = false;
}

void LsmImageStore::EnforceBudget() {
  const std::size_t budget = std::size_t(options_.window_budget_megabytes) << 20;
  while (window_bytes_ > budget && !recency_.empty()) {
    const auto evicted = entries_.find(recency_.back());
    window_bytes_ -= evicted->second.bytes;
    entries_.erase(evicted);
    recency_.pop_back();
  }
}

void LsmImageStore::KeepWindows(image_t image_id, const std::vector<Eigen::Vector2d>& points) {
  Entry& entry = entries_.at(image_id);
  if (!entry.whole) return;
  CutTiles(points, &entry);
  if (search_image_id_ == image_id) {
    search_image_id_ = kInvalidImageId;
    search_pyramid_.clear();
  }
  recency_.push_front(image_id);
  entry.recency = recency_.begin();
  window_bytes_ += entry.bytes;
  EnforceBudget();
}

bool LsmImageStore::MaterializeDeferred(image_t image_id) {
  Entry& entry = entries_.at(image_id);
  cv::Mat grey = entry.deferred_grey();
  if (grey.empty()) {
    recency_.erase(entry.recency);
    entries_.erase(image_id);
    return false;
  }
  entry.levels = BuildLevels(std::move(grey));
  CutTiles(entry.deferred_points, &entry);
  entry.deferred_grey = nullptr;
  entry.deferred_points = {};
  window_bytes_ += entry.bytes;
  // The entry was just used: it is the most recent, never the one evicted.
  recency_.splice(recency_.begin(), recency_, entry.recency);
  EnforceBudget();
  return true;
}

bool LsmImageStore::IsWhole(image_t image_id) const {
  const auto it = entries_.find(image_id);
  return it != entries_.end() && it->second.whole;
}

bool LsmImageStore::HasPixels(image_t image_id) const {
  return entries_.count(image_id) > 0;
}

std::vector<image_t> LsmImageStore::WholeImages() const {
  std::vector<std::pair<std::uint64_t, image_t>> whole;
  for (const auto& [image_id, entry] : entries_) {
    if (entry.whole) whole.emplace_back(entry.arrival, image_id);
  }
  std::sort(whole.begin(), whole.end());
  std::vector<image_t> ids;
  for (const auto& [arrival, image_id] : whole) ids.push_back(image_id);
  return ids;
}

std::vector<LsmImage> LsmImageStore::SearchPyramid(image_t image_id) {
  if (image_id != search_image_id_) {
    // A waiting image that lost its pixels to the budget is searched no
    // more than one kept as windows.
    const auto it = entries_.find(image_id);
    if (it == entries_.end() || !it->second.whole) return {};
    const Entry& entry = it->second;
    // Every level from the 8-bit pyramid the templates of older images are
    // cut from, without the float pixels a search never reads.
    search_pyramid_.clear();
    for (const Level& level : entry.levels) {
      search_pyramid_.push_back(LsmImage::SplineOnly(level.whole));
    }
    search_image_id_ = image_id;
  }
  return search_pyramid_;
}

cv::Mat LsmImageStore::CutFromTiles(const Level& level, const cv::Rect& rect) {
  cv::Mat window(rect.height, rect.width, CV_8U);
  for (int y = rect.y; y < rect.y + rect.height; ++y) {
    std::uint8_t* out = window.ptr<std::uint8_t>(y - rect.y);
    for (int x = rect.x; x < rect.x + rect.width;) {
      const int tx = x / kTile;
      const std::int64_t offset = level.offsets[std::size_t(y / kTile) * level.tiles_x + tx];
      if (offset < 0) return {};
      const int end = std::min(rect.x + rect.width, (tx + 1) * kTile);
      std::memcpy(out + (x - rect.x), &level.tiles[offset + (y % kTile) * kTile + x % kTile],
                  end - x);
      x = end;
    }
  }
  return window;
}

LsmImage LsmImageStore::Window(image_t image_id, int level_index,
                               const Eigen::Vector2d& point, int reach) {
  const auto it = entries_.find(image_id);
  if (it == entries_.end() || level_index < 0 ||
      level_index >= options_.num_pyramid_levels) {
    return {};
  }
  if (it->second.deferred_grey && !MaterializeDeferred(image_id)) return {};
  Entry& entry = entries_.at(image_id);
  const Level& level = entry.levels[level_index];
  const cv::Rect rect = WindowRect(level_index, point, reach, level.width, level.height);
  if (rect.empty()) return {};
  if (entry.whole) return LsmImage(level.whole(rect), rect.x, rect.y);
  recency_.splice(recency_.begin(), recency_, entry.recency);
  const cv::Mat window = CutFromTiles(level, rect);
  if (window.empty()) return {};
  return LsmImage(window, rect.x, rect.y);
}

std::size_t LsmImageStore::whole_bytes() const {
  std::size_t bytes = 0;
  for (const auto& [image_id, entry] : entries_) {
    if (!entry.whole) continue;
    for (const Level& level : entry.levels) bytes += level.whole.total();
  }
  for (const LsmImage& level : search_pyramid_) bytes += level.ByteSize();
  return bytes;
}

void LsmImageStore::WriteWindows(image_t image_id, std::ostream& out) const {
  const Entry& entry = entries_.at(image_id);
  FLYSFM_CHECK(!entry.whole);
  WriteCount(out, entry.levels.size());
  for (const Level& level : entry.levels) {
    WriteValue(out, level.width);
    WriteValue(out, level.height);
    WriteVector(out, level.offsets);
    WriteVector(out, level.tiles);
  }
}

void LsmImageStore::WriteState(std::ostream& out) const {
  WriteValue(out, next_arrival_);
  const std::vector<image_t> whole = WholeImages();
  WriteCount(out, whole.size());
  for (const image_t image_id : whole) {
    WriteValue(out, image_id);
    WriteValue(out, entries_.at(image_id).arrival);
  }
  WriteCount(out, recency_.size());
  for (const image_t image_id : recency_) {
    WriteValue(out, image_id);
    WriteValue(out, entries_.at(image_id).arrival);
  }
}

void LsmImageStore::ReadState(std::istream& in, const GreyLoader& load_grey,
                              const WindowsLoader& load_windows,
                              const PointsLoader& load_points) {
  FLYSFM_CHECK(entries_.empty());
  next_arrival_ = ReadValue<std::uint64_t>(in, "LSM image arrivals");
  const std::size_t num_whole = ReadCount(in, "whole LSM images", std::size_t(1) << 24);
  for (std::size_t i = 0; i < num_whole; ++i) {
    const auto image_id = ReadValue<image_t>(in, "whole LSM image");
    const auto arrival = ReadValue<std::uint64_t>(in, "whole LSM image arrival");
    cv::Mat grey = load_grey(image_id);
    if (grey.empty()) continue;
    Add(image_id, std::move(grey));
    entries_.at(image_id).arrival = arrival;
  }
  const std::size_t num_windowed = ReadCount(in, "LSM images kept as tiles", std::size_t(1) << 24);
  for (std::size_t i = 0; i < num_windowed; ++i) {
    const auto image_id = ReadValue<image_t>(in, "LSM image kept as tiles");
    const auto arrival = ReadValue<std::uint64_t>(in, "LSM image arrival");
    const std::unique_ptr<std::istream> windows = load_windows(image_id);
    Entry entry;
    entry.arrival = arrival;
    entry.whole = false;
    if (!windows) {
      entry.deferred_grey = [load_grey, image_id] { return load_grey(image_id); };
      entry.deferred_points = load_points(image_id);
      recency_.push_back(image_id);
      entry.recency = std::prev(recency_.end());
      entries_[image_id] = std::move(entry);
      continue;
    }
    entry.levels.resize(ReadCount(*windows, "LSM levels", 8));
    if (int(entry.levels.size()) != options_.num_pyramid_levels) continue;
    for (Level& level : entry.levels) {
      level.width = ReadValue<int>(*windows, "LSM level width");
      level.height = ReadValue<int>(*windows, "LSM level height");
      level.offsets = ReadVector<std::int64_t>(*windows, "LSM tile offsets");
      level.tiles = ReadVector<std::uint8_t>(*windows, "LSM tiles", std::size_t(1) << 32);
      if (level.width <= 0 || level.height <= 0) {
        throw std::runtime_error("corrupt LSM windows: bad level size");
      }
      level.tiles_x = (level.width + kTile - 1) / kTile;
      const std::size_t tiles_y = (level.height + kTile - 1) / kTile;
      if (level.offsets.size() != std::size_t(level.tiles_x) * tiles_y) {
        throw std::runtime_error("corrupt LSM windows: tile table of the wrong size");
      }
      for (const std::int64_t offset : level.offsets) {
        if (offset == -1) continue;
        if (offset < 0 || offset % (kTile * kTile) != 0 ||
            offset + kTile * kTile > std::int64_t(level.tiles.size())) {
          throw std::runtime_error("corrupt LSM windows: tile outside the data");
        }
      }
      entry.bytes += level.tiles.size() + level.offsets.size() * sizeof(std::int64_t);
    }
    window_bytes_ += entry.bytes;
    recency_.push_back(image_id);
    entry.recency = std::prev(recency_.end());
    entries_[image_id] = std::move(entry);
  }
}

}  // namespace flysfm
