#pragma once
/// @file adam.hpp
/// Adam (Kingma and Ba), as PyTorch's torch.optim.Adam computes it (bias-corrected moments,
/// optional L2 weight decay added to the gradient), gradient-norm clipping, and a training
/// step that accumulates gradients over micro-batches so a large logical batch fits in memory.

#include <cstdint>
#include <functional>
#include <vector>

#include "ropes_nn/tensor.hpp"

namespace ropes::nn {

struct AdamOptions {
  double lr = 1e-3;
  double beta1 = 0.9;
  double beta2 = 0.999;
  double eps = 1e-8;
  double weight_decay = 0.0;  ///< L2: weight_decay * param is added to the gradient
};

class Adam {
 public:
  /// `params`: leaves that require grad. Throws std::invalid_argument for a parameter that
  /// is not such a leaf, lr <= 0, betas outside [0, 1), eps <= 0 or weight_decay < 0.
  explicit Adam(std::vector<Tensor> params, AdamOptions options = {});

  /// One update with `grads` (one per parameter, same shapes, in the constructor's order).
  /// Per element, in float as PyTorch: g += wd p; m = b1 m + (1 - b1) g;
  /// v = b2 v + (1 - b2) g^2; p -= lr / (1 - b1^t) * m / (sqrt(v) / sqrt(1 - b2^t) + eps).
  void step(const std::vector<Tensor>& grads);
  /// step() with the gradients accumulated in the parameters (Tensor::grad()), which are
  /// then cleared. A parameter without a gradient is skipped and its own update count (the
  /// t of its bias correction) does not advance, as in PyTorch.
  void step();

  std::int64_t steps() const { return steps_; }
  const std::vector<Tensor>& params() const { return params_; }
  const AdamOptions& options() const { return options_; }
  /// First and second moments, one buffer per parameter (for checkpoints).
  std::vector<std::vector<float>>& first_moments() { return m_; }
  std::vector<std::vector<float>>& second_moments() { return v_; }
  /// Restores the step count of a checkpoint (every parameter's update count with it).
  void set_steps(std::int64_t steps);

 private:
  void update(std::size_t i, const Tensor& grad);

  std::vector<Tensor> params_;
  AdamOptions options_;
  std::vector<std::vector<float>> m_, v_;
  std::vector<std::int64_t> param_steps_;  // updates each parameter received (bias correction)
  std::int64_t steps_ = 0;
};

/// Scales `grads` so that their global L2 norm is at most `max_norm` (as PyTorch's
/// clip_grad_norm_), in place. Returns the norm before clipping. max_norm must be > 0.
double clip_grad_norm(std::vector<Tensor>& grads, double max_norm);

/// One optimiser step over a logical batch split into micro-batches. For each i,
/// `micro_batch_loss(i)` returns the mean loss over micro-batch i; weights[i] * its gradient
/// is accumulated (the graph of micro-batch i is freed before i + 1 is built), then the sum
/// is clipped to `clip_norm` (0: no clipping) and applied by `optimizer`. With
/// weights[i] = size_i / batch size this is the gradient of the whole batch's mean loss.
/// Returns sum_i weights[i] * loss_i. Throws std::invalid_argument for empty weights or a
/// non-finite loss (naming the micro-batch), before changing any parameter. A parameter the
/// loss does not depend on gets a zero gradient, so Adam's momentum and weight decay still
/// move it (PyTorch, seeing no gradient, would skip it).
double train_step(Adam& optimizer, const std::function<Tensor(std::size_t)>& micro_batch_loss,
                  const std::vector<double>& weights, double clip_norm = 0.0);

}  // namespace ropes::nn
