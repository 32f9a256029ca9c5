#include "matching/matcher.h"

#include <algorithm>
#include <cmath>
#include <limits>
#include <stdexcept>

#include <opencv2/flann.hpp>

#include "geometry/check.h"

// Fortran BLAS single-precision matrix product (any BLAS: reference, ATLAS,
// OpenBLAS); C = alpha op(A) op(B) + beta C, column-major.
extern "C" void sgemm_(const char* transa, const char* transb, const int* m, const int* n,
                       const int* k, const float* alpha, const float* a, const int* lda,
                       const float* b, const int* ldb, const float* beta, float* c,
                       const int* ldc);

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
  // every distance in both directions. The product goes to BLAS: an optimised
  // sgemm (OpenBLAS picks the CPU's widest vectors at run time) is two to
  // three times Eigen's at the baseline x86-64 flags the project builds with.
  const int n1 = int(d1.rows()), n2 = int(d2.rows()), dims = int(d1.cols());
  KnnResult result;
  result.forward.resize(n1);
  result.backward.assign(n2, -1);
  if (n1 == 0 || n2 == 0) return result;
  // Row-major n1 x n2 = column-major n2 x n1 = d2 (as 128 x n2)^T d1 (128 x n1).
  std::vector<float> dots(std::size_t(n1) * n2);
  const float one = 1, zero = 0;
  sgemm_("T", "N", &n2, &n1, &dims, &one, d2.data(), &dims, d1.data(), &dims, &zero,
         dots.data(), &n2);
  std::vector<float> column_best(n2, -std::numeric_limits<float>::max());
  for (int i = 0; i < n1; ++i) {
    const float* row = dots.data() + std::size_t(i) * n2;
    Neighbours& n = result.forward[i];
    float best = -std::numeric_limits<float>::max(), second = best;
    for (int j = 0; j < n2; ++j) {
      const float v = row[j];
      if (v > second) {
        if (v > best) {
          second = best;
          best = v;
          n.best = j;
        } else {
          second = v;
        }
      }
    }
    n.best_dist2 = SquaredDistanceOfUnitVectors(best);
    if (n2 > 1) n.second_dist2 = SquaredDistanceOfUnitVectors(second);
    // Branch-free, so it vectorises; the owners are found in a second sweep.
    for (int j = 0; j < n2; ++j) column_best[j] = std::max(column_best[j], row[j]);
  }
  for (int i = 0; i < n1; ++i) {
    const float* row = dots.data() + std::size_t(i) * n2;
    for (int j = 0; j < n2; ++j) {
      if (row[j] == column_best[j] && result.backward[j] < 0) result.backward[j] = i;
    }
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
