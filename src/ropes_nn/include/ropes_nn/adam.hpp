#pragma once
/// @file adam.hpp
/// Adam (Kingma and Ba), as PyTorch's torch.optim.Adam computes it (bias-corrected moments,
/// optional L2 weight decay added to the gradient), and gradient-norm clipping. The training
/// step over micro-batches is in train_step.hpp; learning-rate schedules in lr_schedule.hpp;
/// saving and restoring the optimiser's state in checkpoint.hpp.

#include <cstdint>
#include <string>
#include <utility>
#include <vector>

#include "ropes_nn/tensor.hpp"

namespace ropes::nn {

struct AdamOptions {
  double lr = 1e-3;
  double beta1 = 0.9;
  double beta2 = 0.999;
  double eps = 1e-8;
  double weight_decay = 0.0;  ///< L2: weight_decay * param is added to the gradient

  /// What is wrong with these options ("lr=0 ...; expected lr > 0, ..."), or "" when nothing.
  std::string problem() const;
};

class Adam {
 public:
  /// `params`: named leaves that require grad (Module::named_parameters()); the names key
  /// the optimiser's state in checkpoints and error messages. Throws std::invalid_argument
  /// for a parameter that is not such a leaf, an empty or repeated name, lr <= 0, betas
  /// outside [0, 1), eps <= 0 or weight_decay < 0.
  explicit Adam(std::vector<std::pair<std::string, Tensor>> params, AdamOptions options = {});
  /// The same with parameters named "param.0", "param.1", ... in order.
  explicit Adam(const std::vector<Tensor>& params, AdamOptions options = {});

  /// One update with `grads` (one per parameter, same shapes, in the constructor's order; an
  /// undefined tensor skips its parameter). Per element, in float as PyTorch: g += wd p;
  /// m = b1 m + (1 - b1) g; v = b2 v + (1 - b2) g^2;
  /// p -= lr / (1 - b1^t) * m / (sqrt(v) / sqrt(1 - b2^t) + eps), t the parameter's own
  /// update count.
  void step(const std::vector<Tensor>& grads);
  /// step() with the gradients accumulated in the parameters (Tensor::grad()), which are
  /// then cleared. A parameter without a gradient is skipped and its own update count (the
  /// t of its bias correction) does not advance, as in PyTorch.
  void step();

  /// The learning rate of the next step. set_lr: lr >= 0 and finite (a schedule may reach 0),
  /// else std::invalid_argument.
  double lr() const { return options_.lr; }
  void set_lr(double lr);
  /// Replaces every hyperparameter (checked as the constructor does).
  void set_options(const AdamOptions& options);

  std::int64_t steps() const { return steps_; }
  const std::vector<Tensor>& params() const { return params_; }
  const std::vector<std::string>& names() const { return names_; }
  const AdamOptions& options() const { return options_; }

  /// The state of parameter i (constructor order), for checkpoints: first and second
  /// moments (numel floats each) and the number of updates it received.
  std::vector<float>& first_moment(std::size_t i) { return m_.at(i); }
  std::vector<float>& second_moment(std::size_t i) { return v_.at(i); }
  const std::vector<float>& first_moment(std::size_t i) const { return m_.at(i); }
  const std::vector<float>& second_moment(std::size_t i) const { return v_.at(i); }
  std::int64_t param_steps(std::size_t i) const { return param_steps_.at(i); }
  void set_param_steps(std::size_t i, std::int64_t steps);
  /// Restores the step count of a checkpoint (every parameter's update count with it).
  void set_steps(std::int64_t steps);

 private:
  void update(std::size_t i, const Tensor& grad);

  std::vector<Tensor> params_;
  std::vector<std::string> names_;
  AdamOptions options_;
  std::vector<std::vector<float>> m_, v_;
  std::vector<std::int64_t> param_steps_;  // updates each parameter received (bias correction)
  std::int64_t steps_ = 0;
};

/// Scales `grads` so that their global L2 norm is at most `max_norm` (as PyTorch's
/// clip_grad_norm_), in place. Returns the norm before clipping. max_norm must be > 0.
double clip_grad_norm(std::vector<Tensor>& grads, double max_norm);

}  // namespace ropes::nn
