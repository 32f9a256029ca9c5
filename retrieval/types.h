#pragma once

#include <Eigen/Core>

namespace flysfm {

// Sets of vectors, one per row (k-means points, global descriptors).
using RowMatrixXf = Eigen::Matrix<float, Eigen::Dynamic, Eigen::Dynamic, Eigen::RowMajor>;

// Same size and bit-identical values (Eigen's == needs equal sizes).
template <typename A, typename B>
bool IdenticalMatrices(const Eigen::MatrixBase<A>& a, const Eigen::MatrixBase<B>& b) {
  return a.rows() == b.rows() && a.cols() == b.cols() && a == b;
}

}  // namespace flysfm
