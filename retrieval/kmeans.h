#pragma once

// Lloyd's k-means with k-means++ seeding, shared by the VLAD codebook and the
// vocabulary tree.

#include <cstdint>
#include <vector>

#include "retrieval/types.h"

namespace flysfm {

struct KMeansOptions {
  // Lloyd iterations; stops earlier once no assignment changes.
  int num_iterations = 10;
  std::uint32_t seed = 0;

  bool Check() const { return num_iterations >= 1; }
};

// Index of the nearest row of `centres` for every row of `points` (ties to
// the lower index).
std::vector<int> AssignToNearest(const RowMatrixXf& points, const RowMatrixXf& centres);

// Clusters the rows of `points` into at most k centres, one per row of the
// result (fewer when there are fewer points, or fewer distinct points, than
// k); `assignment` (optional) receives each point's centre. Deterministic for
// a seed. Needs k >= 1 and at least one point.
RowMatrixXf KMeans(const RowMatrixXf& points, int k, const KMeansOptions& options,
                   std::vector<int>* assignment = nullptr);

}  // namespace flysfm
