#include "matching/matcher.h"

#include <cmath>
#include <limits>
#include <stdexcept>

#include <opencv2/flann.hpp>

#include "geometry/check.h"

namespace flysfm {
namespace {

// The two nearest neighbours of one query, as squared Euclidean distances.
struct Neighbours {
  int best = -1;
  float best_dist2 = std::numeric_limits<float>::max();
  float second_dist2 = std::numeric_limits<float>::max();
};

struct KnnResult {
  std::vector<Neighbours> forward;  // for each row of image 1, in image 2
  std::vector<int> backward;        // for each row of image 2, best in image 1
};

float SquaredDistanceOfUnitVectors(float dot) { return std::max(0.f, 2.f - 2.f * dot); }

KnnResult ExactKnn(const FeatureDescriptors& d1, const FeatureDescriptors& d2) {
  // RootSIFT rows have unit norm: |a - b|^2 = 2 - 2 a.b, so one product gives
  // every distance in both directions; one row-major sweep reads both.
  using RowMajorMatrix = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;
  // Dynamic-size views: with the fixed 128 columns GCC warns (falsely) about
  // Eigen's matrix-vector kernel.
  const Eigen::Map<const RowMajorMatrix> a(d1.data(), d1.rows(), d1.cols());
  const Eigen::Map<const RowMajorMatrix> b(d2.data(), d2.rows(), d2.cols());
  const RowMajorMatrix dots = a * b.transpose();
  KnnResult result;
  result.forward.resize(d1.rows());
  result.backward.assign(d2.rows(), -1);
  std::vector<float> column_best(d2.rows(), -std::numeric_limits<float>::max());
  for (Eigen::Index i = 0; i < dots.rows(); ++i) {
    const float* row = dots.row(i).data();
    Neighbours& n = result.forward[i];
    float best = -std::numeric_limits<float>::max(), second = best;
    for (Eigen::Index j = 0; j < dots.cols(); ++j) {
      const float v = row[j];
      if (v > best) {
        second = best;
        best = v;
        n.best = int(j);
      } else if (v > second) {
        second = v;
      }
      if (v > column_best[j]) {
        column_best[j] = v;
        result.backward[j] = int(i);
      }
    }
    n.best_dist2 = SquaredDistanceOfUnitVectors(best);
    if (dots.cols() > 1) n.second_dist2 = SquaredDistanceOfUnitVectors(second);
  }
  return result;
}

cv::Mat WrapAsMat(const FeatureDescriptors& d) {
  return cv::Mat(int(d.rows()), 128, CV_32F, const_cast<float*>(d.data()));
}

// For each row of `query`, its k nearest rows of `train`: indices and squared
// distances (k columns, -1 where train has fewer rows).
void FlannSearch(const FeatureDescriptors& train, const FeatureDescriptors& query,
                 int k, const MatchOptions& options, cv::Mat* indices,
                 cv::Mat* dists2) {
  cv::flann::Index index(WrapAsMat(train),
                         cv::flann::KDTreeIndexParams(options.flann_num_trees),
                         cvflann::FLANN_DIST_L2);
  *indices = cv::Mat(int(query.rows()), k, CV_32S, cv::Scalar(-1));
  *dists2 = cv::Mat(int(query.rows()), k, CV_32F,
                    cv::Scalar(std::numeric_limits<float>::max()));
  index.knnSearch(WrapAsMat(query), *indices, *dists2, std::min<int>(k, int(train.rows())),
                  cv::flann::SearchParams(options.flann_num_checks));
}

KnnResult ApproximateKnn(const FeatureDescriptors& d1, const FeatureDescriptors& d2,
                         const MatchOptions& options) {
  KnnResult result;
  cv::Mat indices, dists2;
  FlannSearch(d2, d1, 2, options, &indices, &dists2);
  result.forward.resize(d1.rows());
  for (int i = 0; i < indices.rows; ++i) {
    Neighbours& n = result.forward[i];
    n.best = indices.at<int>(i, 0);
    n.best_dist2 = dists2.at<float>(i, 0);
    if (indices.cols > 1 && indices.at<int>(i, 1) >= 0) {
      n.second_dist2 = dists2.at<float>(i, 1);
    }
  }
  if (options.mutual) {
    FlannSearch(d1, d2, 1, options, &indices, &dists2);
    result.backward.resize(d2.rows());
    for (int j = 0; j < indices.rows; ++j) result.backward[j] = indices.at<int>(j, 0);
  }
  return result;
}

}  // namespace

bool MatchOptions::Check() const {
  return max_ratio > 0 && max_ratio <= 1 && max_distance > 0 && flann_num_trees >= 1 &&
         flann_num_checks >= 1;
}

std::vector<FeatureMatch> MatchDescriptors(const FeatureDescriptors& descriptors1,
                                           const FeatureDescriptors& descriptors2,
                                           const MatchOptions& options) {
  if (!options.Check()) throw std::invalid_argument("invalid MatchOptions");
  std::vector<FeatureMatch> matches;
  if (descriptors1.rows() == 0 || descriptors2.rows() == 0) return matches;

  const KnnResult knn = options.backend == MatcherBackend::kExact
                            ? ExactKnn(descriptors1, descriptors2)
                            : ApproximateKnn(descriptors1, descriptors2, options);
  const float max_ratio2 = float(options.max_ratio * options.max_ratio);
  const float max_distance2 = float(options.max_distance * options.max_distance);
  for (int i = 0; i < int(knn.forward.size()); ++i) {
    const Neighbours& n = knn.forward[i];
    if (n.best < 0 || n.best_dist2 > max_distance2) continue;
    // With a single candidate there is no second neighbour to compare with;
    // the ratio test cannot vouch for the match, so it is dropped.
    if (n.second_dist2 == std::numeric_limits<float>::max()) continue;
    if (n.best_dist2 >= max_ratio2 * n.second_dist2) continue;
    if (options.mutual) {
      FLYSFM_CHECK(n.best < int(knn.backward.size()));
      if (knn.backward[n.best] != i) continue;
    }
    matches.push_back({i, n.best});
  }
  return matches;
}

}  // namespace flysfm
