#include "core/lsm_image_store.h"

#include <algorithm>
#include <map>
#include <memory>
#include <random>
#include <sstream>

#include <catch2/catch.hpp>
#include <opencv2/core.hpp>
#include <opencv2/imgproc.hpp>

namespace flysfm {
namespace {

// Band-limited random texture: what LSM converges on.
cv::Mat Texture(int width, int height, int seed) {
  cv::Mat noise(height, width, CV_32F);
  cv::theRNG().state = seed;
  cv::randu(noise, 0, 255);
  cv::GaussianBlur(noise, noise, cv::Size(0, 0), 1.5);
  cv::Mat grey;
  cv::normalize(noise, noise, 0, 255, cv::NORM_MINMAX);
  noise.convertTo(grey, CV_8U);
  return grey;
}

std::vector<Eigen::Vector2d> RandomPoints(int count, int width, int height, int seed) {
  std::mt19937 rng(seed);
  std::uniform_real_distribution<double> x(0, width - 1), y(0, height - 1);
  std::vector<Eigen::Vector2d> points;
  for (int i = 0; i < count; ++i) points.emplace_back(x(rng), y(rng));
  return points;
}

// Matches each point from `start_offset` away, with image 1's template once
// from the whole pyramid level and once from the store's window; both must
// end at the same place.
void CheckWindowsMatchLikeWholeImage(LsmImageStore* store, image_t image_id,
                                     const std::vector<LsmImage>& whole, int level, int reach,
                                     const std::vector<Eigen::Vector2d>& points,
                                     const Eigen::Vector2d& window_offset, double tolerance_px) {
  LsmMatcher matcher{LsmOptions()};
  const double scale = 1.0 / (1 << level);
  const Eigen::Vector2d start_offset(0.6, -0.4);
  int num_converged = 0;
  for (const Eigen::Vector2d& point : points) {
    const Eigen::Vector2d at_level = scale * point;
    const LsmImage window = store->Window(image_id, level, point, reach);
    REQUIRE_FALSE(window.empty());
    const LsmResult from_whole = matcher.Match(whole[level], at_level, whole[level],
                                               at_level + start_offset,
                                               Eigen::Matrix2d::Identity(), window_offset);
    const LsmResult from_window = matcher.Match(window, at_level, whole[level],
                                                at_level + start_offset,
                                                Eigen::Matrix2d::Identity(), window_offset);
    CHECK(from_window.status == from_whole.status);
    if (!from_whole.Converged() || !from_window.Converged()) continue;
    ++num_converged;
    CHECK((from_window.point2 - from_whole.point2).norm() < tolerance_px);
  }
  CHECK(num_converged > int(points.size()) / 2);
}

// A default store holding image 1 whole (a 400 x 300 texture), and the
// image's float pyramid built apart.
struct OneImageStore {
  explicit OneImageStore(int seed)
      : grey(Texture(400, 300, seed)),
        whole(BuildLsmPyramid(grey, options.num_pyramid_levels)) {
    store.Add(1, grey);
  }
  LsmImageStore::Options options;
  LsmImageStore store{options};
  cv::Mat grey;
  std::vector<LsmImage> whole;
};

TEST_CASE("A template cut from the kept windows matches as the whole image does") {
  OneImageStore one(1);
  const LsmImageStore::Options& options = one.options;
  LsmImageStore& store = one.store;
  const std::vector<LsmImage>& whole = one.whole;
  // Away from the border, where the whole image's windows fit too.
  std::vector<Eigen::Vector2d> points;
  for (const Eigen::Vector2d& point : RandomPoints(60, 300, 200, 2)) {
    points.push_back(point + Eigen::Vector2d(50, 50));
  }
  const int reach0 = options.template_reach_px;
  const int coarse_reach = options.coarse_template_reach_px;
  const Eigen::Vector2d shift(options.template_reach_px - LsmTemplateReach(LsmOptions()), 0);
  // The spline context of a window (LsmTemplateReach) keeps its
  // coefficients within 4e-4 of a grey-level step of the whole image's: far
  // below a thousandth of a pixel in position.
  const double exact = 1e-3;
  SECTION("while the image is whole") {
    CheckWindowsMatchLikeWholeImage(&store, 1, whole, 0, reach0, points, shift, exact);
  }
  SECTION("once only the windows are kept") {
    store.KeepWindows(1, points);
    REQUIRE_FALSE(store.IsWhole(1));
    REQUIRE(store.HasPixels(1));
    CHECK(store.SearchPyramid(1).empty());
    CheckWindowsMatchLikeWholeImage(&store, 1, whole, 0, reach0, points, Eigen::Vector2d::Zero(),
                                    exact);
    CheckWindowsMatchLikeWholeImage(&store, 1, whole, 0, reach0, points, shift, exact);
    // The coarse levels are kept in 8 bits (the whole pyramid's are float):
    // half a grey level of rounding moves a converged window by a few
    // hundredths of a pixel at most, where only a start within the 2 px
    // basin of the next level is needed.
    for (int level = 1; level < options.num_pyramid_levels; ++level) {
      CheckWindowsMatchLikeWholeImage(&store, 1, whole, level, coarse_reach, points,
                                      Eigen::Vector2d::Zero(), 0.05);
    }
    // Nothing is kept far from every point.
    CHECK(store.Window(1, 0, Eigen::Vector2d(5, 5), reach0).empty() ==
          (std::none_of(points.begin(), points.end(), [&](const Eigen::Vector2d& p) {
            return (p - Eigen::Vector2d(5, 5)).lpNorm<Eigen::Infinity>() < 2 * reach0 + 32;
          })));
  }
}

TEST_CASE("A search pyramid holds spline coefficients only and matches as the float one") {
  OneImageStore one(3);
  const LsmImageStore::Options& options = one.options;
  const std::vector<LsmImage>& whole = one.whole;
  const std::vector<LsmImage> search = one.store.SearchPyramid(1);
  REQUIRE(search.size() == whole.size());
  LsmMatcher matcher{LsmOptions()};
  for (int level = 0; level < options.num_pyramid_levels; ++level) {
    CAPTURE(level);
    CHECK_FALSE(search[level].has_pixels());
    CHECK(search[level].ByteSize() * 2 == whole[level].ByteSize());
    REQUIRE(search[level].width() == whole[level].width());
    REQUIRE(search[level].height() == whole[level].height());
    // Level 0 is the same image, so the same coefficients; the coarser
    // levels come from the 8-bit pyramid (the float pyramid's within half a
    // grey level), as the templates of older images do.
    const double tolerance_px = level == 0 ? 1e-6 : 0.05;
    const double scale = 1.0 / (1 << level);
    int num_converged = 0;
    for (const Eigen::Vector2d& point : RandomPoints(40, 300, 200, 4)) {
      const Eigen::Vector2d at_level = scale * (point + Eigen::Vector2d(50, 50));
      const Eigen::Vector2d start = at_level + Eigen::Vector2d(0.6, -0.4);
      const LsmResult in_whole = matcher.Match(whole[level], at_level, whole[level], start,
                                               Eigen::Matrix2d::Identity());
      const LsmResult in_search = matcher.Match(whole[level], at_level, search[level], start,
                                                Eigen::Matrix2d::Identity());
      CHECK(in_search.status == in_whole.status);
      if (!in_whole.Converged() || !in_search.Converged()) continue;
      ++num_converged;
      CHECK((in_search.point2 - in_whole.point2).norm() < tolerance_px);
    }
    CHECK(num_converged > 20);
  }
}

TEST_CASE("Older images keep only their windows, within the budget, least recently used out") {
  LsmImageStore::Options options;
  const int width = 1600, height = 1200;
  // 60 points on a 1 600 x 1 200 image: their windows cover part of it.
  const std::vector<Eigen::Vector2d> points = RandomPoints(60, width, height, 7);
  std::size_t one = 0;
  {
    LsmImageStore store(options);
    for (image_t id = 1; id <= 2; ++id) store.Add(id, Texture(width, height, id));
    CHECK(store.WholeImages() == std::vector<image_t>{1, 2});
    const std::size_t whole_pyramid = store.whole_bytes() / 2;
    CHECK(whole_pyramid >= std::size_t(width) * height);
    // A whole image is searched in its spline pyramid, built once and kept
    // for the next call.
    const std::vector<LsmImage> search = store.SearchPyramid(2);
    REQUIRE(search.size() == std::size_t(options.num_pyramid_levels));
    CHECK(search[0].width() == width);
    CHECK(store.SearchPyramid(2)[0].spline_coefficients() == search[0].spline_coefficients());
    const std::size_t before = store.whole_bytes();
    store.KeepWindows(1, points);
    CHECK(store.WholeImages() == std::vector<image_t>{2});
    CHECK(store.whole_bytes() == before - whole_pyramid);
    one = store.window_bytes();
    CHECK(one > 0);
    CHECK(one < whole_pyramid);
  }

  // Two such images fit in 1 MB, three do not: the least recently read
  // one goes.
  options.window_budget_megabytes = 1;
  const std::size_t budget = std::size_t(1) << 20;
  REQUIRE(2 * one <= budget);
  REQUIRE(3 * one > budget);
  LsmImageStore store(options);
  for (image_t id = 1; id <= 4; ++id) store.Add(id, Texture(width, height, id));
  store.KeepWindows(1, points);
  store.KeepWindows(2, points);
  CHECK(store.window_bytes() == 2 * one);
  CHECK_FALSE(store.Window(1, 0, points[0], options.template_reach_px).empty());
  store.KeepWindows(3, points);
  CHECK(store.HasPixels(1));
  CHECK_FALSE(store.HasPixels(2));
  CHECK(store.Window(2, 0, points[0], options.template_reach_px).empty());
  // An image without pixels left (a shot that waited long) has nothing to
  // search, as one kept as windows.
  CHECK(store.SearchPyramid(2).empty());
  CHECK(store.SearchPyramid(3).empty());
  CHECK(store.HasPixels(3));
  CHECK(store.window_bytes() == 2 * one);
  store.KeepWindows(4, points);
  CHECK_FALSE(store.HasPixels(1));
  CHECK(store.HasPixels(3));
  CHECK(store.WholeImages().empty());

  options.num_pyramid_levels = 0;
  CHECK_THROWS_AS(LsmImageStore(options), std::invalid_argument);
}

}  // namespace
}  // namespace flysfm

namespace flysfm {
namespace {

// Every window of `ids` around `points`, at every level, is the same pixels
// in both stores.
void CheckSameWindows(const std::vector<image_t>& ids, const std::vector<Eigen::Vector2d>& points,
                      LsmImageStore* a, LsmImageStore* b) {
  const LsmImageStore::Options options;
  for (const image_t id : ids) {
    for (int level = 0; level < options.num_pyramid_levels; ++level) {
      for (const Eigen::Vector2d& point : points) {
        const LsmImage wa = a->Window(id, level, point, options.coarse_template_reach_px);
        const LsmImage wb = b->Window(id, level, point, options.coarse_template_reach_px);
        REQUIRE(wa.width() == wb.width());
        REQUIRE(wa.height() == wb.height());
        CHECK(std::equal(wa.data(), wa.data() + wa.width() * wa.height(), wb.data()));
      }
    }
  }
}

}  // namespace

TEST_CASE("A store restored from its checkpoint gives the same windows and keeps the same order") {
  LsmImageStore::Options options;
  const int width = 640, height = 480;
  const std::vector<Eigen::Vector2d> points = RandomPoints(40, width, height, 3);
  LsmImageStore original(options);
  for (image_t id = 1; id <= 4; ++id) original.Add(id, Texture(width, height, id));
  original.KeepWindows(2, points);
  original.KeepWindows(1, points);

  std::map<image_t, std::string> windows;
  for (const image_t id : {image_t(1), image_t(2)}) {
    std::ostringstream out;
    original.WriteWindows(id, out);
    windows[id] = out.str();
  }
  std::stringstream state;
  original.WriteState(state);
  LsmImageStore restored(options);
  restored.ReadState(
      state, [&](image_t id) { return Texture(width, height, int(id)); },
      [&](image_t id) { return std::make_unique<std::istringstream>(windows.at(id)); },
      [&](image_t) { return points; });
  CHECK(restored.WholeImages() == original.WholeImages());
  CHECK(restored.window_bytes() == original.window_bytes());
  CheckSameWindows({1, 2, 3}, points, &original, &restored);

  // Tiles not written are cut again from the image's pixels around its
  // points, when LSM first reads them; a restore decodes nothing before.
  state.clear();
  state.seekg(0);
  LsmImageStore deferred(options);
  int num_decoded = 0;
  deferred.ReadState(
      state,
      [&](image_t id) {
        ++num_decoded;
        return Texture(width, height, int(id));
      },
      [](image_t) { return std::unique_ptr<std::istream>(); }, [&](image_t) { return points; });
  const int num_whole = int(original.WholeImages().size());
  CHECK(num_decoded == num_whole);
  CheckSameWindows({1, 2}, points, &original, &deferred);
  CHECK(num_decoded == num_whole + 2);
  CHECK(deferred.window_bytes() == original.window_bytes());

  // An image whose pixels cannot be had again is left out, as if dropped.
  state.clear();
  state.seekg(0);
  LsmImageStore partial(options);
  partial.ReadState(
      state, [](image_t) { return cv::Mat(); },
      [](image_t) { return std::unique_ptr<std::istream>(); }, [&](image_t) { return points; });
  CHECK(partial.WholeImages().empty());
  CHECK(partial.Window(1, 0, points[0], options.template_reach_px).width() == 0);
  CHECK_FALSE(partial.HasPixels(1));
  CHECK(partial.window_bytes() == 0);

  // A corrupt tile table is refused.
  std::string bad = windows.at(1);
  bad.resize(bad.size() / 3);
  state.clear();
  state.seekg(0);
  LsmImageStore refused(options);
  CHECK_THROWS_AS(
      refused.ReadState(
          state, [&](image_t id) { return Texture(width, height, int(id)); },
          [&](image_t) { return std::make_unique<std::istringstream>(bad); },
          [&](image_t) { return points; }),
      std::runtime_error);
}

}  // namespace flysfm
