#pragma once
/// @file sparsity_objective.hpp
/// The AE2 objective of ROPES in autodiff form (paper, eq. "loss_function"):
///   L = E_all || y - g(h(y)) ||^2 / (C*8*8)  +  lambda * sum_k || E_k |J_g(z)^T v_k(y)| - e_{t_k}
///   ||
/// with z = h(y), v_k the score differences of joint k (the frozen LDR_k's input gradient)
/// and E_k the mean over joint k's samples; t_k is the latent that estimates joint k. The
/// norm is squared L2 (the paper) or L1. The batch means sit inside the norm, so the loss is
/// declared to ropes_nn's train_step as an outer function of batch means: a step over any
/// number of micro-batches equals the whole-batch step.
///
/// With ae2.input_normalization "standardize" the objective is written in AE2's coordinates
/// s = ae2.coordinates(y): the reconstruction error is || s - g(h(y)) ||^2 and v_k must be
/// given in those coordinates too (CodeStandardization::to_mapped_gradient of the LDR's
/// gradient); J_g^T v_k is then the same number as in y's coordinates, up to v's scaling.
#include "ropes_crl/networks.hpp"
#include "ropes_crl/score_sparsity.hpp"

#include <ropes_nn/train_step.hpp>

#include <vector>

namespace ropes::crl {

/// J_g(z)^T v for each sample: z = ae2.encode(y), y_hat = ae2.decode(z), the
/// vector-Jacobian product of y_hat with v at z. y, v: [n, C, 8, 8] -> [n, d]. With
/// `create_graph` the result can be differentiated (the training step needs it).
Tensor latent_score_differences(Ae2& ae2, const Tensor& y, const Tensor& v, bool create_graph);

/// v with each sample scaled to unit L2 length (samples of length 0 stay 0). [n, ...].
Tensor unit_length_rows(const Tensor& v);
/// v divided by one number, the mean L2 length of its samples (all 0: v unchanged), so
/// the mean length is 1 and the samples keep their relative sizes. [n, ...].
Tensor mean_unit_length_rows(const Tensor& v);

/// || mean_abs - e_target ||, squared L2 or L1. mean_abs: [d]; 0 <= target < d. With
/// `signed_mean` ([d], the batch mean of J_g^T v without the absolute value) entry `target`
/// of mean_abs is replaced by |signed_mean[target]| (SparsityDiagonal::kAbsMean).
Tensor sparsity_penalty(const Tensor& mean_abs, std::int64_t target, SparsityNorm norm,
                        const Tensor& signed_mean = Tensor());

/// One AE2 training batch: reconstruction samples and, per sparsity term, samples with their
/// score differences.
struct Ae2Batch {
  Tensor reconstruction;              ///< y [n_r, C, 8, 8]
  std::vector<Tensor> term_codes;     ///< y [n_k, C, 8, 8] per term
  std::vector<Tensor> term_scores;    ///< v [n_k, C, 8, 8] per term
  std::vector<std::int64_t> targets;  ///< t_k per term
  /// ae2.logit_loss (an extension): per term, LDR_k's standardised logit at each
  /// reconstruction sample ([n_r]); empty, or logit_weight 0, for none
  std::vector<Tensor> term_logits;
  double logit_weight = 0;
};

/// 1 - corr(z, l) from the batch means m = [E z, E z^2, E z l, E l, E l^2] ([5]): the logit
/// term of one sparsity term. A constant z or l has correlation 0 (eps 1e-12 under the root).
Tensor logit_correlation_loss(const Tensor& m);

/// The objective over `batch` split into micro-batches of at most `micro_batch` rows (all
/// sets split into the same number of parts). Statistic 0 is the reconstruction error,
/// statistic 1 + k is |J_g^T v_k| (its mean is row k of the sparsity matrix). With
/// lambda == 0 no sparsity statistic is computed and the loss is affine. `*micro_batches`
/// receives the number of parts (StepOptions::micro_batches). The returned loss refers to
/// `ae2` and `batch`: both must outlive it.
/// With SparsityDiagonal::kAbsMean the signed J_g^T v_k follow as statistics 1 + K + k
/// (K terms), so statistic 1 + k is row k of the sparsity matrix in both forms. With the
/// logit term the last K statistics are its moments per term (logit_correlation_loss), on
/// the reconstruction samples; it applies whatever lambda is.
nn::BatchLoss ae2_batch_loss(Ae2& ae2, const Ae2Batch& batch, double lambda, SparsityNorm norm,
                             std::int64_t micro_batch, std::size_t* micro_batches,
                             SparsityDiagonal diagonal = SparsityDiagonal::kMeanAbs);

}  // namespace ropes::crl
