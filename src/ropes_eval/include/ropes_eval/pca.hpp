#pragma once
/// @file pca.hpp
/// Principal component analysis, the label-free baseline of the evaluation: the leading
/// principal components of AE1's code as estimates of the joints (what the score-sparsity
/// term has to beat without any labels).

#include <Eigen/Core>

namespace ropes::eval {

/// A fitted PCA: x -> (x - mean) * components, one principal component a column.
struct Pca {
  Eigen::RowVectorXd mean;     ///< [d], the fitted samples' mean
  Eigen::MatrixXd components;  ///< [d, k], orthonormal, by decreasing variance
  Eigen::VectorXd variance;    ///< [k], the variance (n - 1) along each component

  /// The scores of `x` ([n, d]): [n, k]. Throws std::invalid_argument when x has another
  /// number of columns than the fit.
  Eigen::MatrixXd project(const Eigen::Ref<const Eigen::MatrixXd>& x) const;
};

/// The k leading principal components of the rows of `x` ([n, d]), from the eigenvectors of
/// the sample covariance (Eigen's SelfAdjointEigenSolver; O(n d^2 + d^3)). Each component's
/// sign is fixed so that its entry of largest magnitude is positive, so a fit does not
/// depend on the solver's sign choice. Throws std::invalid_argument when n < 2, k < 1,
/// k > d, or a value is not finite.
Pca fit_pca(const Eigen::Ref<const Eigen::MatrixXd>& x, Eigen::Index k);

}  // namespace ropes::eval
