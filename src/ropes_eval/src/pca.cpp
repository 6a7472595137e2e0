#include "ropes_eval/pca.hpp"

#include <Eigen/Eigenvalues>

#include <cmath>
#include <sstream>
#include <stdexcept>

#include "finite_check.hpp"
#include "ropes_nn/parallel.hpp"

namespace ropes::eval {

Eigen::MatrixXd Pca::project(const Eigen::Ref<const Eigen::MatrixXd>& x) const {
  if (x.cols() != mean.size()) {
    std::ostringstream message;
    message << "Pca::project: samples of " << x.cols() << " values; the fit has " << mean.size();
    throw std::invalid_argument(message.str());
  }
  return (x.rowwise() - mean) * components;
}

Pca fit_pca(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::Index k) {
  // the same blocking of the products below on every CPU (see ropes_nn/parallel.hpp)
  nn::pin_eigen_blocking();
  const Eigen::Index n = x.rows(), d = x.cols();
  if (n < 2 || k < 1 || k > d) {
    std::ostringstream message;
    message << "fit_pca: " << k << " components of " << n << " samples of " << d
            << " values; expected at least 2 samples and 1 <= components <= values";
    throw std::invalid_argument(message.str());
  }
  detail::require_finite("fit_pca", "x", x);
  Pca p;
  p.mean = x.colwise().mean();
  const Eigen::MatrixXd centred = x.rowwise() - p.mean;
  const Eigen::MatrixXd covariance = (centred.transpose() * centred) / static_cast<double>(n - 1);
  const Eigen::SelfAdjointEigenSolver<Eigen::MatrixXd> solver(covariance);
  // the solver sorts eigenvalues increasingly: the leading components are the last columns
  p.components.resize(d, k);
  p.variance.resize(k);
  for (Eigen::Index i = 0; i < k; ++i) {
    Eigen::VectorXd v = solver.eigenvectors().col(d - 1 - i);
    Eigen::Index largest = 0;
    v.cwiseAbs().maxCoeff(&largest);
    if (v(largest) < 0)
      v = -v;
    p.components.col(i) = v;
    p.variance(i) = solver.eigenvalues()(d - 1 - i);
  }
  return p;
}

}  // namespace ropes::eval
