#include "retrieval/pca_whitening.h"

#include <algorithm>
#include <cmath>
#include <random>
#include <stdexcept>

#include <Eigen/Eigenvalues>
#include <Eigen/QR>

#include "geometry/check.h"
#include "retrieval/binary_io.h"

namespace flysfm {

namespace {

// The `k` largest eigenpairs of the symmetric positive semi-definite `m`,
// eigenvalues descending. Small matrices are decomposed fully; large ones by
// subspace iteration on k + 16 vectors, whose cost is O(m^2 k) instead of
// O(m^3): the leading eigenpairs, the ones kept, converge first.
void TopEigenpairs(const Eigen::MatrixXd& m, int k, Eigen::VectorXd* values,
                   Eigen::MatrixXd* vectors) {
  const Eigen::Index size = m.rows();
  const Eigen::Index width = std::min<Eigen::Index>(size, k + 16);
  Eigen::MatrixXd basis;
  if (size <= 2 * width) {
    basis = Eigen::MatrixXd::Identity(size, size);
  } else {
    std::mt19937 rng(1);
    std::normal_distribution<double> normal(0.0, 1.0);
    basis = Eigen::MatrixXd::NullaryExpr(size, width, [&]() { return normal(rng); });
    constexpr int kIterations = 6;
    for (int i = 0; i < kIterations; ++i) {
      const Eigen::MatrixXd product = m * basis;
      basis = Eigen::HouseholderQR<Eigen::MatrixXd>(product).householderQ() *
              Eigen::MatrixXd::Identity(size, width);
    }
  }
  const Eigen::MatrixXd reduced = basis.transpose() * m * basis;
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(reduced);
  FLYSFM_CHECK(solver.info() == Eigen::Success);
  const Eigen::Index keep = std::min<Eigen::Index>(k, reduced.rows());
  values->resize(keep);
  vectors->resize(size, keep);
  for (Eigen::Index j = 0; j < keep; ++j) {
    const Eigen::Index source = reduced.rows() - 1 - j;  // ascending order
    (*values)[j] = std::max(0.0, solver.eigenvalues()[source]);
    vectors->col(j) = basis * solver.eigenvectors().col(source);
  }
}

}  // namespace

PcaWhitening PcaWhitening::Train(const RowMatrixXf& samples, int out_dim,
                                 double regularisation) {
  FLYSFM_CHECK(samples.rows() >= 2 && out_dim >= 1 && regularisation >= 0);
  const Eigen::Index n = samples.rows();
  const Eigen::Index d = samples.cols();
  PcaWhitening pca;
  pca.mean_ = samples.colwise().mean().transpose();
  const RowMatrixXf centred = samples.rowwise() - pca.mean_.transpose();
  // X^T X (d x d) and X X^T (n x n) share their non-zero eigenvalues mu; an
  // eigenvector u of X X^T gives the principal direction X^T u / sqrt(mu).
  // The smaller of the two is decomposed: X X^T for VLAD (n << d).
  const bool use_gram = n < d;
  const Eigen::MatrixXd scatter =
      use_gram ? (centred * centred.transpose()).cast<double>().eval()
               : (centred.transpose() * centred).cast<double>().eval();
  Eigen::VectorXd mu;
  Eigen::MatrixXd vectors;
  TopEigenpairs(scatter, int(std::min<Eigen::Index>(out_dim, n - 1)), &mu, &vectors);
  const double tiny = 1e-9 * std::max(mu.size() > 0 ? mu[0] : 0.0, 1e-30);
  int dim = 0;
  while (dim < mu.size() && mu[dim] > tiny) ++dim;
  FLYSFM_CHECK(dim >= 1);
  // Eigenvalues of the covariance are mu / (n - 1).
  const double mean_lambda = mu.head(dim).sum() / double(n - 1) / dim;

  RowMatrixXf coefficients(dim, use_gram ? n : d);
  for (int k = 0; k < dim; ++k) {
    const double lambda = mu[k] / double(n - 1);
    double scale = 1.0 / std::sqrt(lambda + regularisation * mean_lambda);
    if (use_gram) scale /= std::sqrt(mu[k]);
    coefficients.row(k) = (vectors.col(k) * scale).cast<float>().transpose();
  }
  pca.projection_ = use_gram ? RowMatrixXf(coefficients * centred) : coefficients;
  return pca;
}

Eigen::VectorXf PcaWhitening::Apply(const Eigen::VectorXf& x) const {
  FLYSFM_CHECK(x.size() == mean_.size());
  return projection_ * (x - mean_);
}

void PcaWhitening::Write(std::ostream& out) const {
  WriteMatrix(out, mean_.transpose());
  WriteMatrix(out, projection_);
}

PcaWhitening PcaWhitening::Read(std::istream& in) {
  PcaWhitening pca;
  const RowMatrixXf mean = ReadMatrix(in, "PCA mean");
  pca.projection_ = ReadMatrix(in, "PCA projection");
  if (mean.rows() > 1 || (pca.projection_.size() > 0 && pca.projection_.cols() != mean.cols())) {
    throw std::runtime_error("corrupt model file: PCA sizes disagree");
  }
  pca.mean_ = mean.size() > 0 ? Eigen::VectorXf(mean.row(0).transpose()) : Eigen::VectorXf();
  return pca;
}

}  // namespace flysfm
