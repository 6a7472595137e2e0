#pragma once
/// @file correlation.hpp
/// Correlation measures for disentanglement: Pearson, Spearman and the per-joint mean
/// correlation coefficient (MCC) of the ROPES paper.
///
/// MCC as the paper reports it pairs latent i with joint i and takes |Pearson|; Spearman
/// (rank) correlation is offered beside it because the paper's identifiability result holds
/// only up to a monotonic transform of each latent.

#include <Eigen/Core>

#include <vector>

namespace ropes::eval {

/// Which correlation a per-joint score uses.
enum class Correlation { kPearson, kSpearman };

/// Pearson's r of two samples of equal length n >= 2, computed in two passes (mean, then
/// centred sums) for accuracy. Throws std::invalid_argument when the lengths differ, n < 2,
/// a value is not finite, or either sample is constant (r undefined), naming which.
double pearson(const Eigen::Ref<const Eigen::VectorXd>& x,
               const Eigen::Ref<const Eigen::VectorXd>& y);

/// Spearman's rho: Pearson's r of the ranks, ties given their average rank (as
/// scipy.stats.spearmanr does). Same preconditions as pearson().
double spearman(const Eigen::Ref<const Eigen::VectorXd>& x,
                const Eigen::Ref<const Eigen::VectorXd>& y);

/// 1-based ranks of `x`, ties sharing their average rank ([1, 2, 2, 4] -> [1, 2.5, 2.5, 4]).
/// Cost O(n log n). Throws std::invalid_argument for a non-finite value.
Eigen::VectorXd average_ranks(const Eigen::Ref<const Eigen::VectorXd>& x);

/// Per-joint |correlation| between latent column j and joint column j.
/// `latents` and `angles`: [n, k] with the same shape, one sample per row.
/// Returns a k-vector; its mean is the MCC. Throws std::invalid_argument on a shape
/// mismatch (printing both shapes) or when a column pair violates pearson()'s preconditions
/// (naming the column).
Eigen::VectorXd per_joint_correlation(const Eigen::Ref<const Eigen::MatrixXd>& latents,
                                      const Eigen::Ref<const Eigen::MatrixXd>& angles,
                                      Correlation kind = Correlation::kPearson);

/// The |correlation| of every joint with every latent: entry (j, l) = |corr(angles column
/// j, latents column l)|, a [k, d] matrix. `latents` [n, d], `angles` [n, k], n >= 2 rows
/// each. Throws std::invalid_argument on a row-count mismatch or when a column is constant
/// or not finite (naming the joint or the latent column).
Eigen::MatrixXd correlation_matrix(const Eigen::Ref<const Eigen::MatrixXd>& latents,
                                   const Eigen::Ref<const Eigen::MatrixXd>& angles,
                                   Correlation kind = Correlation::kPearson);

/// A matching of joints to distinct latents.
struct Assignment {
  std::vector<Eigen::Index> latent_of_joint;  ///< joint j is matched to latent latent_of_joint[j]
  Eigen::VectorXd correlation;                ///< the matched entries, one a joint
  double mean = 0;                            ///< their mean: the best-assignment MCC
};

/// The assignment of rows (joints) to distinct columns (latents) with the largest sum of
/// `weights` ([k, d], k <= d; the |correlation| matrix): the Hungarian algorithm
/// (shortest augmenting paths with potentials), O(k^2 d), exact. Among assignments of equal
/// sum, the one returned depends on the matrix alone. Throws std::invalid_argument for
/// k > d, an empty matrix or a value that is not finite.
Assignment best_assignment(const Eigen::Ref<const Eigen::MatrixXd>& weights);

/// The best-assignment MCC of the CRL literature: best_assignment(correlation_matrix(...)).
/// It does not use the paper's pairing of latent i with joint i; the paper's measure is
/// per_joint_correlation().
Assignment best_assignment_correlation(const Eigen::Ref<const Eigen::MatrixXd>& latents,
                                       const Eigen::Ref<const Eigen::MatrixXd>& angles,
                                       Correlation kind = Correlation::kPearson);

}  // namespace ropes::eval
