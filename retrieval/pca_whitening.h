#pragma once

// PCA projection with (regularised) whitening, learnt from sample vectors.

#include <istream>
#include <ostream>

#include "retrieval/types.h"

namespace flysfm {

class PcaWhitening {
 public:
  // Learns the mean and the `out_dim` principal directions of the rows of
  // `samples` (fewer when there are fewer than out_dim + 1 samples). Each
  // direction is scaled by 1 / sqrt(lambda + regularisation * mean_lambda):
  // plain whitening for regularisation 0; a positive value keeps the noisy
  // low-variance directions, poorly estimated from few samples, from being
  // blown up. Uses the Gram matrix, so the cost is O(n^2 d) for n samples of
  // dimension d, cheap when n << d as for VLAD.
  static PcaWhitening Train(const RowMatrixXf& samples, int out_dim,
                            double regularisation);

  int InputDim() const { return int(mean_.size()); }
  int OutputDim() const { return int(projection_.rows()); }
  bool empty() const { return projection_.rows() == 0; }

  Eigen::VectorXf Apply(const Eigen::VectorXf& x) const;

  void Write(std::ostream& out) const;
  static PcaWhitening Read(std::istream& in);

  bool operator==(const PcaWhitening& other) const {
    return IdenticalMatrices(mean_, other.mean_) &&
           IdenticalMatrices(projection_, other.projection_);
  }

 private:
  Eigen::VectorXf mean_;
  // OutputDim x InputDim, whitening scale folded in.
  RowMatrixXf projection_;
};

}  // namespace flysfm
