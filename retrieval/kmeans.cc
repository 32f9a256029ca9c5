#include "retrieval/kmeans.h"

#include <algorithm>
#include <limits>
#include <random>

#include "geometry/check.h"

namespace flysfm {
namespace {

// Squared distances of every point to its nearest centre, with the index.
void Nearest(const RowMatrixXf& points, const RowMatrixXf& centres,
             std::vector<int>* index, std::vector<float>* dist2) {
  const Eigen::VectorXf centre_norms = centres.rowwise().squaredNorm();
  index->assign(points.rows(), 0);
  if (dist2) dist2->assign(points.rows(), 0.f);
  // Blocks bound the size of the distance matrix for large point sets.
  constexpr Eigen::Index kBlock = 4096;
  for (Eigen::Index start = 0; start < points.rows(); start += kBlock) {
    const Eigen::Index count = std::min(kBlock, points.rows() - start);
    const RowMatrixXf dots = points.middleRows(start, count) * centres.transpose();
    for (Eigen::Index i = 0; i < count; ++i) {
      Eigen::Index best = 0;
      (centre_norms.transpose() - 2.f * dots.row(i)).minCoeff(&best);
      (*index)[start + i] = int(best);
      if (dist2) {
        (*dist2)[start + i] =
            std::max(0.f, (points.row(start + i) - centres.row(best)).squaredNorm());
      }
    }
  }
}

}  // namespace

std::vector<int> AssignToNearest(const RowMatrixXf& points, const RowMatrixXf& centres) {
  FLYSFM_CHECK(centres.rows() >= 1 && points.cols() == centres.cols());
  std::vector<int> index;
  Nearest(points, centres, &index, nullptr);
  return index;
}

RowMatrixXf KMeans(const RowMatrixXf& points, int k, const KMeansOptions& options,
                   std::vector<int>* assignment) {
  FLYSFM_CHECK(k >= 1 && points.rows() >= 1 && options.Check());
  const Eigen::Index n = points.rows();
  std::mt19937 rng(options.seed);
  std::vector<int> labels;

  if (n <= k) {
    if (assignment) {
      assignment->resize(n);
      for (Eigen::Index i = 0; i < n; ++i) (*assignment)[i] = int(i);
    }
    return points;
  }

  // k-means++: each new centre drawn with probability proportional to the
  // squared distance to the nearest centre chosen so far.
  RowMatrixXf centres(k, points.cols());
  centres.row(0) = points.row(std::uniform_int_distribution<Eigen::Index>(0, n - 1)(rng));
  std::vector<float> dist2(n);
  for (Eigen::Index i = 0; i < n; ++i) dist2[i] = (points.row(i) - centres.row(0)).squaredNorm();
  int num_centres = 1;
  for (; num_centres < k; ++num_centres) {
    double total = 0;
    for (float d : dist2) total += d;
    if (total <= 0) break;  // every point coincides with a centre
    std::uniform_real_distribution<double> uniform(0.0, total);
    double target = uniform(rng);
    Eigen::Index chosen = n - 1;
    for (Eigen::Index i = 0; i < n; ++i) {
      target -= dist2[i];
      if (target <= 0) {
        chosen = i;
        break;
      }
    }
    centres.row(num_centres) = points.row(chosen);
    for (Eigen::Index i = 0; i < n; ++i) {
      dist2[i] = std::min(dist2[i], (points.row(i) - centres.row(num_centres)).squaredNorm());
    }
  }
  centres.conservativeResize(num_centres, Eigen::NoChange);

  std::vector<int> previous;
  for (int iteration = 0; iteration < options.num_iterations; ++iteration) {
    Nearest(points, centres, &labels, &dist2);
    if (labels == previous) break;
    RowMatrixXf sums = RowMatrixXf::Zero(centres.rows(), points.cols());
    std::vector<int> counts(centres.rows(), 0);
    for (Eigen::Index i = 0; i < n; ++i) {
      sums.row(labels[i]) += points.row(i);
      ++counts[labels[i]];
    }
    for (Eigen::Index c = 0; c < centres.rows(); ++c) {
      if (counts[c] > 0) {
        centres.row(c) = sums.row(c) / float(counts[c]);
      } else {
        // An empty cluster takes over the point farthest from its centre.
        const auto far = std::max_element(dist2.begin(), dist2.end()) - dist2.begin();
        centres.row(c) = points.row(far);
        dist2[far] = 0.f;
      }
    }
    previous = labels;
  }
  if (assignment) Nearest(points, centres, assignment, nullptr);
  return centres;
}

}  // namespace flysfm
