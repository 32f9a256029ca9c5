// bench_photos --profile: an offline look at why two-view verification
// costs more on photos than on 640x480 frames. Sample pairs of the session
// are matched and verified again with each RANSAC timed, then the same
// matches are verified in the pixel scale of the 1600 px feature image and
// of a 640 px frame; and one LSM pyramid is built at full resolution and at
// 640x480.

#include "bench/photo_profile.h"

#include <algorithm>
#include <chrono>
#include <cstdio>
#include <map>
#include <vector>

#include <opencv2/imgproc.hpp>

#include "geometry/statistics.h"
#include "geometry/two_view_geometry.h"
#include "lsm/lsm.h"
#include "matching/matcher.h"

namespace flysfm::bench {
namespace {

using Clock = std::chrono::steady_clock;

double MsSince(Clock::time_point start) {
  return std::chrono::duration<double, std::milli>(Clock::now() - start).count();
}

// Times of one pair's verification (ms) and what it found.
struct PairProfile {
  int raw_matches = 0;
  double match_ms = 0;
  double f_ms = 0, h_ms = 0, e_ms = 0;
  int f_iterations = 0, h_iterations = 0, e_iterations = 0;
  // EstimateCalibratedTwoViewGeometry on the same matches, in the pixels of
  // the photo, of the 1600 px feature image and of a 640 px wide frame.
  double full_ms = 0, feature_scale_ms = 0, video_scale_ms = 0;
  int full_inliers = 0, feature_scale_inliers = 0, video_scale_inliers = 0;
};

Camera Scaled(const Camera& camera, double scale) {
  Camera scaled = camera;
  for (double& p : scaled.params) p *= scale;
  scaled.width = int(std::round(camera.width * scale));
  scaled.height = int(std::round(camera.height * scale));
  return scaled;
}

}  // namespace

nlohmann::json ProfilePhotoPairs(const std::vector<Frame>& frames, const Camera& camera,
                                 const Engine::Options& options) {
  const int n = int(frames.size());
  std::map<int, PreparedFrame> prepared;
  const auto get = [&](int i) -> const PreparedFrame& {
    auto it = prepared.find(i);
    if (it == prepared.end()) it = prepared.emplace(i, Engine::Prepare(frames[i], options)).first;
    return it->second;
  };
  // Near pairs (1-4 shots apart) overlap; pairs 10 and 25 shots apart
  // mostly do not, like the low-ranked retrieval candidates the engine still
  // verifies when fewer than max_verified_pairs of them verify.
  std::vector<std::pair<int, int>> pairs;
  for (int k = 1; k <= 4; ++k) {
    const int i = k * n / 5;
    for (const int back : {1, 2, 4, 10, 25}) {
      if (i - back >= 0 && i < n) pairs.emplace_back(i, i - back);
    }
  }
  const TwoViewGeometryOptions& two_view = options.verification.two_view;
  RansacOptions ransac = two_view.ransac;
  ransac.max_error = two_view.max_error_px;
  std::vector<PairProfile> profiles;
  std::printf("\nprofile: sample pairs verified again offline (ms; RANSAC iterations)\n"
              "  pair        raw   match   F (it)      H (it)      E (it)      two-view at "
              "photo / 1600 px / 640 px scale (inliers)\n");
  for (const auto& [i, j] : pairs) {
    const FeatureSet& a = get(i).features;
    const FeatureSet& b = get(j).features;
    PairProfile p;
    auto start = Clock::now();
    const std::vector<FeatureMatch> raw =
        MatchDescriptors(RootSift(a.descriptors), RootSift(b.descriptors),
                         options.verification.matching);
    p.match_ms = MsSince(start);
    p.raw_matches = int(raw.size());
    std::vector<Eigen::Vector2d> pa, pb, na, nb;
    for (const FeatureMatch& m : raw) {
      pa.emplace_back(a.keypoints[m.idx1].x, a.keypoints[m.idx1].y);
      pb.emplace_back(b.keypoints[m.idx2].x, b.keypoints[m.idx2].y);
      na.push_back(camera.CamFromImg(pa.back()));
      nb.push_back(camera.CamFromImg(pb.back()));
    }
    if (int(raw.size()) >= two_view.min_num_inliers_f) {
      start = Clock::now();
      const auto f = EstimateFundamentalMatrix(pa, pb, ransac);
      p.f_ms = MsSince(start);
      p.f_iterations = f.num_iterations;
      start = Clock::now();
      const auto h = EstimateHomographyMatrix(pa, pb, ransac);
      p.h_ms = MsSince(start);
      p.h_iterations = h.num_iterations;
      RansacOptions ransac_e = ransac;
      ransac_e.max_error = two_view.max_error_px / camera.MeanFocalLength();
      start = Clock::now();
      const auto e = EstimateEssentialMatrix(na, nb, ransac_e);
      p.e_ms = MsSince(start);
      p.e_iterations = e.num_iterations;
      const auto at_scale = [&](double scale, double* ms, int* inliers) {
        std::vector<Eigen::Vector2d> sa = pa, sb = pb;
        for (auto& x : sa) x *= scale;
        for (auto& x : sb) x *= scale;
        const Camera c = Scaled(camera, scale);
        const auto begin = Clock::now();
        const TwoViewGeometry g = EstimateCalibratedTwoViewGeometry(c, sa, c, sb, two_view);
        *ms = MsSince(begin);
        *inliers = g.num_inliers;
      };
      at_scale(1.0, &p.full_ms, &p.full_inliers);
      const double feature_scale =
          std::min(1.0, double(options.sift.max_image_size) / std::max(camera.width, camera.height));
      at_scale(feature_scale, &p.feature_scale_ms, &p.feature_scale_inliers);
      at_scale(640.0 / camera.width, &p.video_scale_ms, &p.video_scale_inliers);
    }
    std::printf("  %4d-%-4d %6d %7.1f %6.1f (%5d) %5.1f (%5d) %5.1f (%5d)   %6.1f (%d) / "
                "%6.1f (%d) / %6.1f (%d)\n",
                i, j, p.raw_matches, p.match_ms, p.f_ms, p.f_iterations, p.h_ms, p.h_iterations,
                p.e_ms, p.e_iterations, p.full_ms, p.full_inliers, p.feature_scale_ms,
                p.feature_scale_inliers, p.video_scale_ms, p.video_scale_inliers);
    profiles.push_back(p);
  }
  const auto median_of = [&](auto field, int verified) {
    // verified: 1 pairs with enough inliers, 0 without, -1 all.
    std::vector<double> values;
    for (const PairProfile& p : profiles) {
      const bool ok = p.full_inliers >= two_view.min_num_inliers_f;
      if (verified < 0 || ok == bool(verified)) values.push_back(double(p.*field));
    }
    return Median(values);
  };
  nlohmann::json json = {{"pairs", profiles.size()}};
  for (const auto& [label, verified] :
       std::vector<std::pair<std::string, int>>{{"verified", 1}, {"failed", 0}}) {
    int count = 0;
    for (const PairProfile& p : profiles) {
      count += (p.full_inliers >= two_view.min_num_inliers_f) == bool(verified);
    }
    json[label] = {
        {"pairs", count},
        {"median_raw_matches", median_of(&PairProfile::raw_matches, verified)},
        {"median_match_ms", median_of(&PairProfile::match_ms, verified)},
        {"median_f_ms", median_of(&PairProfile::f_ms, verified)},
        {"median_h_ms", median_of(&PairProfile::h_ms, verified)},
        {"median_e_ms", median_of(&PairProfile::e_ms, verified)},
        {"median_f_iterations", median_of(&PairProfile::f_iterations, verified)},
        {"median_h_iterations", median_of(&PairProfile::h_iterations, verified)},
        {"median_e_iterations", median_of(&PairProfile::e_iterations, verified)},
        {"median_two_view_ms_photo_px", median_of(&PairProfile::full_ms, verified)},
        {"median_two_view_ms_feature_px", median_of(&PairProfile::feature_scale_ms, verified)},
        {"median_two_view_ms_640px", median_of(&PairProfile::video_scale_ms, verified)},
        {"median_inliers_photo_px", median_of(&PairProfile::full_inliers, verified)},
        {"median_inliers_feature_px", median_of(&PairProfile::feature_scale_inliers, verified)},
        {"median_inliers_640px", median_of(&PairProfile::video_scale_inliers, verified)}};
    const nlohmann::json& j = json[label];
    std::printf("  median of the %d %s pairs: %.0f raw matches; match %.1f ms; F %.1f ms (%.0f "
                "it), H %.1f ms (%.0f it), E %.1f ms (%.0f it); two-view %.1f ms in photo "
                "pixels, %.1f ms in 1600 px, %.1f ms in 640 px (inliers %.0f / %.0f / %.0f)\n",
                count, label.c_str(), j["median_raw_matches"].get<double>(),
                j["median_match_ms"].get<double>(), j["median_f_ms"].get<double>(),
                j["median_f_iterations"].get<double>(), j["median_h_ms"].get<double>(),
                j["median_h_iterations"].get<double>(), j["median_e_ms"].get<double>(),
                j["median_e_iterations"].get<double>(),
                j["median_two_view_ms_photo_px"].get<double>(),
                j["median_two_view_ms_feature_px"].get<double>(),
                j["median_two_view_ms_640px"].get<double>(),
                j["median_inliers_photo_px"].get<double>(),
                j["median_inliers_feature_px"].get<double>(),
                j["median_inliers_640px"].get<double>());
  }
  // Decoding and SIFT of the sampled photos, run here with the engine idle:
  // against the run's figures, what sharing the two cores costs.
  std::vector<double> decode_ms, features_ms;
  for (const auto& [index, frame] : prepared) {
    decode_ms.push_back(frame.decode_ms);
    features_ms.push_back(frame.features_ms);
  }
  json["alone_decode_ms"] = Median(decode_ms);
  json["alone_features_ms"] = Median(features_ms);
  std::printf("  decode %.0f ms, features %.0f ms (medians of the %zu sampled photos prepared "
              "alone, engine idle)\n",
              Median(decode_ms), Median(features_ms), decode_ms.size());

  // LSM reads whole-resolution pyramids: their cost and size at this
  // resolution against a 640x480 frame's.
  const cv::Mat& grey = get(pairs.empty() ? 0 : pairs.front().first).grey;
  cv::Mat small;
  cv::resize(grey, small, cv::Size(640, 480), 0, 0, cv::INTER_AREA);
  const int levels = options.lsm_images.num_pyramid_levels;
  const auto pyramid = [&](const cv::Mat& image, double* ms, double* mb) {
    const auto begin = Clock::now();
    const std::vector<LsmImage> built = BuildLsmPyramid(image, levels);
    *ms = MsSince(begin);
    std::size_t bytes = 0;
    for (const LsmImage& level : built) bytes += level.ByteSize();
    *mb = bytes / 1048576.0;
  };
  double photo_ms, photo_mb, frame_ms, frame_mb;
  pyramid(grey, &photo_ms, &photo_mb);
  pyramid(small, &frame_ms, &frame_mb);
  std::printf("  LSM search pyramid (%d levels, built once for each new photo): %.0f ms and "
              "%.1f MB at %dx%d, %.1f ms and %.2f MB at 640x480; a whole 8-bit grey photo is "
              "%.1f MB (older photos keep only windows, within %d MB)\n",
              levels, photo_ms, photo_mb, grey.cols, grey.rows, frame_ms, frame_mb,
              grey.total() / 1048576.0, options.lsm_images.window_budget_megabytes);
  json["lsm_pyramid_ms_photo"] = photo_ms;
  json["lsm_pyramid_mb_photo"] = photo_mb;
  json["lsm_pyramid_ms_640x480"] = frame_ms;
  json["lsm_pyramid_mb_640x480"] = frame_mb;
  json["grey_mb_per_photo"] = grey.total() / 1048576.0;
  return json;
}

}  // namespace flysfm::bench
