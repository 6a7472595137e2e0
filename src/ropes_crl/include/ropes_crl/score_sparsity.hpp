#pragma once
/// @file score_sparsity.hpp
/// The score-sparsity term of the ROPES loss (paper, eq. "loss_function"), evaluated on
/// given latent-space score differences.
///
/// For joint i, each row of `latent_score_diffs` is one sample of
///   J_g(z_hat)^T (s_q^i(x) - s_qbar^i(x)),
/// the image-space score difference pulled back to the latent space through the decoder's
/// Jacobian. The paper's sparsity loss is
///   || E[ |row| ] - e_i ||_2^2,
/// which is zero exactly when the expected absolute score difference is one in coordinate i
/// and zero elsewhere. This function evaluates that value in double precision: the training
/// loop differentiates its own autodiff form, and this one is its reference and a metric.

#include <Eigen/Core>

#include <string>

namespace ropes::crl {

/// How the distance between E|Delta s| and e_i is measured (DESIGN.md, "Decisions").
enum class SparsityNorm {
  kL2Squared,  ///< || . ||_2^2, the paper's form (config value "l2sq", the default)
  kL1,         ///< entrywise L1 || . ||_1, as in the authors' earlier public code ("l1")
};

/// What stands for the intervened latent's entry of the sparsity row (the other entries are
/// always E|Delta s_j|).
enum class SparsityDiagonal {
  kMeanAbs,  ///< E|Delta s_i|, the paper's form (config value "mean_abs", the default)
  kAbsMean,  ///< |E Delta s_i|: a latent whose response to v_i changes sign across samples
             ///< (a latent that folds the joint) is penalised ("abs_mean")
};

/// Parses "mean_abs" or "abs_mean". Throws std::invalid_argument naming the value otherwise.
SparsityDiagonal parse_sparsity_diagonal(const std::string& name);
/// The config spelling of `diagonal`.
const char* to_string(SparsityDiagonal diagonal);

/// Parses "l2sq" or "l1". Throws std::invalid_argument naming the value otherwise.
SparsityNorm parse_sparsity_norm(const std::string& name);
/// The config spelling of `norm`: "l2sq" or "l1".
const char* to_string(SparsityNorm norm);

/// E[|Delta s|] over the rows of `latent_score_diffs` ([n, d]): a d-vector.
/// Throws std::invalid_argument when n == 0, d == 0 or an entry is not finite (naming the
/// row and column).
Eigen::VectorXd mean_abs_score_difference(
    const Eigen::Ref<const Eigen::MatrixXd>& latent_score_diffs);

/// The sparsity loss || E[|Delta s|] - e_target ||, squared L2 or L1 per `norm`; with
/// SparsityDiagonal::kAbsMean entry `target` of E[|Delta s|] is |E[Delta s_target]|.
/// `latent_score_diffs`: [n, d], one sample per row. `target`: the intervened latent,
/// 0 <= target < d. Throws std::invalid_argument for a target out of range and for the
/// inputs mean_abs_score_difference rejects.
double score_sparsity_loss(const Eigen::Ref<const Eigen::MatrixXd>& latent_score_diffs, int target,
                           SparsityNorm norm = SparsityNorm::kL2Squared,
                           SparsityDiagonal diagonal = SparsityDiagonal::kMeanAbs);

}  // namespace ropes::crl
