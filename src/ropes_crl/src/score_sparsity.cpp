#include "ropes_crl/score_sparsity.hpp"

#include <cmath>
#include <sstream>
#include <stdexcept>

namespace ropes::crl {

SparsityNorm parse_sparsity_norm(const std::string& name) {
  if (name == "l2sq")
    return SparsityNorm::kL2Squared;
  if (name == "l1")
    return SparsityNorm::kL1;
  throw std::invalid_argument("sparsity_norm: '" + name +
                              "' is not a norm; expected 'l2sq' or 'l1'");
}

const char* to_string(SparsityNorm norm) {
  return norm == SparsityNorm::kL1 ? "l1" : "l2sq";
}

SparsityDiagonal parse_sparsity_diagonal(const std::string& name) {
  if (name == "mean_abs")
    return SparsityDiagonal::kMeanAbs;
  if (name == "abs_mean")
    return SparsityDiagonal::kAbsMean;
  throw std::invalid_argument("sparsity_diagonal: '" + name +
                              "' is not a form of the diagonal; expected 'mean_abs' or 'abs_mean'");
}

const char* to_string(SparsityDiagonal diagonal) {
  return diagonal == SparsityDiagonal::kAbsMean ? "abs_mean" : "mean_abs";
}

Eigen::VectorXd mean_abs_score_difference(
    const Eigen::Ref<const Eigen::MatrixXd>& latent_score_diffs) {
  const Eigen::Index n = latent_score_diffs.rows();
  const Eigen::Index d = latent_score_diffs.cols();
  if (n == 0 || d == 0) {
    std::ostringstream message;
    message << "mean_abs_score_difference: score differences have shape [" << n << ", " << d
            << "]; expected at least one sample and one latent";
    throw std::invalid_argument(message.str());
  }
  // report the first non-finite entry by position
  for (Eigen::Index i = 0; i < n; ++i) {
    for (Eigen::Index j = 0; j < d; ++j) {
      if (!std::isfinite(latent_score_diffs(i, j))) {
        std::ostringstream message;
        message << "mean_abs_score_difference: score difference [" << i << ", " << j << "] is "
                << latent_score_diffs(i, j) << "; expected a finite value";
        throw std::invalid_argument(message.str());
      }
    }
  }
  return latent_score_diffs.cwiseAbs().colwise().mean().transpose();
}

double score_sparsity_loss(const Eigen::Ref<const Eigen::MatrixXd>& latent_score_diffs, int target,
                           SparsityNorm norm, SparsityDiagonal diagonal) {
  const Eigen::Index d = latent_score_diffs.cols();
  if (target < 0 || target >= d) {
    std::ostringstream message;
    message << "score_sparsity_loss: target latent " << target << " is out of range; expected 0 <= "
            << "target < " << d << " (the number of latent columns)";
    throw std::invalid_argument(message.str());
  }
  Eigen::VectorXd residual = mean_abs_score_difference(latent_score_diffs);
  if (diagonal == SparsityDiagonal::kAbsMean)
    residual(target) = std::fabs(latent_score_diffs.col(target).mean());
  residual(target) -= 1.0;
  return norm == SparsityNorm::kL1 ? residual.lpNorm<1>() : residual.squaredNorm();
}

}  // namespace ropes::crl
