#include "retrieval/pca_whitening.h"

#include <random>
#include <sstream>

#include <catch2/catch.hpp>
#include <Eigen/QR>

namespace flysfm {
namespace {

TEST_CASE("PCA-whitening finds the principal subspace and whitens it") {
  // Samples in 20-D with variance 9, 4, 1 along three orthonormal directions
  // and tiny noise elsewhere.
  std::mt19937 rng(2);
  std::normal_distribution<float> normal(0.f, 1.f);
  Eigen::MatrixXf basis = Eigen::MatrixXf::Random(20, 3);
  basis = Eigen::HouseholderQR<Eigen::MatrixXf>(basis).householderQ() * Eigen::MatrixXf::Identity(20, 3);
  const Eigen::Vector3f sigma(3.f, 2.f, 1.f);
  const int n = 4000;
  RowMatrixXf samples(n, 20);
  Eigen::VectorXf offset = Eigen::VectorXf::Constant(20, 5.f);
  for (int i = 0; i < n; ++i) {
    Eigen::Vector3f c(normal(rng), normal(rng), normal(rng));
    Eigen::VectorXf x = offset + basis * sigma.cwiseProduct(c);
    for (int d = 0; d < 20; ++d) x[d] += 1e-3f * normal(rng);
    samples.row(i) = x.transpose();
  }
  const PcaWhitening pca = PcaWhitening::Train(samples, 3, 0.0);
  REQUIRE(pca.OutputDim() == 3);
  REQUIRE(pca.InputDim() == 20);
  // Whitened outputs: zero mean, identity covariance (to sampling error, ~3 %).
  Eigen::MatrixXf out(n, 3);
  for (int i = 0; i < n; ++i) out.row(i) = pca.Apply(samples.row(i).transpose()).transpose();
  const Eigen::RowVectorXf mean = out.colwise().mean();
  CHECK(mean.norm() < 1e-3);
  const Eigen::MatrixXf cov = out.transpose() * out / float(n - 1);
  CHECK((cov - Eigen::Matrix3f::Identity()).cwiseAbs().maxCoeff() < 0.05);
  // Regularisation shrinks the weight of the low-variance direction most.
  const PcaWhitening damped = PcaWhitening::Train(samples, 3, 1.0);
  Eigen::MatrixXf out2(n, 3);
  for (int i = 0; i < n; ++i) out2.row(i) = damped.Apply(samples.row(i).transpose()).transpose();
  const Eigen::Vector3f var2 = (out2.transpose() * out2 / float(n - 1)).diagonal();
  CHECK(var2[2] < var2[0]);

  std::stringstream stream;
  pca.Write(stream);
  CHECK(PcaWhitening::Read(stream) == pca);
}

TEST_CASE("PCA-whitening with fewer samples than dimensions whitens its training set") {
  // 300 samples in 1 000-D (the Gram-matrix path with subspace iteration, as
  // for VLAD): on its own training samples an exact PCA-whitening gives an
  // identity covariance, whatever the sampling error.
  std::mt19937 rng(3);
  std::normal_distribution<float> normal(0.f, 1.f);
  const int n = 300, d = 1000, k = 40;
  RowMatrixXf samples(n, d);
  for (int i = 0; i < n; ++i) {
    for (int j = 0; j < d; ++j) {
      // Variance falling with the coordinate: a clear spectrum to recover.
      samples(i, j) = normal(rng) * (j < 60 ? 10.f / (1 + j) : 0.01f);
    }
  }
  const PcaWhitening pca = PcaWhitening::Train(samples, k, 0.0);
  REQUIRE(pca.OutputDim() == k);
  Eigen::MatrixXf out(n, k);
  for (int i = 0; i < n; ++i) out.row(i) = pca.Apply(samples.row(i).transpose()).transpose();
  const Eigen::MatrixXf cov = out.transpose() * out / float(n - 1);
  CHECK((cov - Eigen::MatrixXf::Identity(k, k)).cwiseAbs().maxCoeff() < 0.02);
}

}  // namespace
}  // namespace flysfm
