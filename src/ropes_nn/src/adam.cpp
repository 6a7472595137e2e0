#include "ropes_nn/adam.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>
#include <string>

#include "ropes_nn/ops.hpp"

namespace ropes::nn {

Adam::Adam(std::vector<Tensor> params, AdamOptions options)
    : params_(std::move(params)), options_(options) {
  const auto& o = options_;
  if (!(o.lr > 0) || !(o.beta1 >= 0 && o.beta1 < 1) || !(o.beta2 >= 0 && o.beta2 < 1) ||
      !(o.eps > 0) || !(o.weight_decay >= 0)) {
    throw std::invalid_argument(
        "Adam: lr=" + std::to_string(o.lr) + " beta1=" + std::to_string(o.beta1) +
        " beta2=" + std::to_string(o.beta2) + " eps=" + std::to_string(o.eps) +
        " weight_decay=" + std::to_string(o.weight_decay) +
        "; expected lr > 0, betas in [0, 1), eps > 0, weight_decay >= 0");
  }
  for (std::size_t i = 0; i < params_.size(); ++i) {
    if (!params_[i].defined() || !params_[i].requires_grad() || !params_[i].is_leaf()) {
      throw std::invalid_argument("Adam: parameter " + std::to_string(i) +
                                  " is not a leaf tensor that requires grad");
    }
    m_.emplace_back(static_cast<std::size_t>(params_[i].numel()), 0.0f);
    param_steps_.push_back(0);
    v_.emplace_back(static_cast<std::size_t>(params_[i].numel()), 0.0f);
  }
}

void Adam::update(std::size_t i, const Tensor& grad) {
  Tensor& p = params_[i];
  if (grad.shape() != p.shape()) {
    throw std::invalid_argument("Adam::step: gradient " + std::to_string(i) + " has shape " +
                                grad.shape().str() + "; its parameter has " + p.shape().str());
  }
  const auto b1 = static_cast<float>(options_.beta1);
  const auto b2 = static_cast<float>(options_.beta2);
  const auto wd = static_cast<float>(options_.weight_decay);
  const auto eps = static_cast<float>(options_.eps);
  const double t = static_cast<double>(++param_steps_[i]);
  const auto step_size = static_cast<float>(options_.lr / (1.0 - std::pow(options_.beta1, t)));
  const auto correction2_sqrt = static_cast<float>(std::sqrt(1.0 - std::pow(options_.beta2, t)));
  float* w = p.mutable_data();
  const float* g = grad.data();
  float* m = m_[i].data();
  float* v = v_[i].data();
  for (std::int64_t k = 0; k < p.numel(); ++k) {
    const float gk = wd != 0.0f ? g[k] + wd * w[k] : g[k];
    m[k] = b1 * m[k] + (1.0f - b1) * gk;
    v[k] = b2 * v[k] + (1.0f - b2) * gk * gk;
    w[k] -= step_size * m[k] / (std::sqrt(v[k]) / correction2_sqrt + eps);
  }
}

void Adam::set_steps(std::int64_t steps) {
  steps_ = steps;
  std::fill(param_steps_.begin(), param_steps_.end(), steps);
}

void Adam::step(const std::vector<Tensor>& grads) {
  if (grads.size() != params_.size()) {
    throw std::invalid_argument("Adam::step: " + std::to_string(grads.size()) + " gradients for " +
                                std::to_string(params_.size()) + " parameters");
  }
  ++steps_;
  for (std::size_t i = 0; i < params_.size(); ++i) {
    if (grads[i].defined())
      update(i, grads[i]);
  }
}

void Adam::step() {
  std::vector<Tensor> grads;
  for (Tensor& p : params_)
    grads.push_back(p.grad());
  step(grads);
  for (Tensor& p : params_)
    p.zero_grad();
}

double clip_grad_norm(std::vector<Tensor>& grads, double max_norm) {
  if (!(max_norm > 0)) {
    throw std::invalid_argument("clip_grad_norm: max_norm " + std::to_string(max_norm) +
                                "; expected > 0");
  }
  double total = 0.0;
  for (const Tensor& g : grads) {
    if (!g.defined())
      continue;
    const float* p = g.data();
    for (std::int64_t k = 0; k < g.numel(); ++k)
      total += static_cast<double>(p[k]) * p[k];
  }
  const double norm = std::sqrt(total);
  // PyTorch: clip_coef = max_norm / (norm + 1e-6), applied when below 1
  const double coef = max_norm / (norm + 1e-6);
  if (coef < 1.0) {
    for (Tensor& g : grads) {
      if (!g.defined())
        continue;
      float* p = g.mutable_data();
      for (std::int64_t k = 0; k < g.numel(); ++k)
        p[k] = static_cast<float>(p[k] * coef);
    }
  }
  return norm;
}

double train_step(Adam& optimizer, const std::function<Tensor(std::size_t)>& micro_batch_loss,
                  const std::vector<double>& weights, double clip_norm) {
  if (weights.empty())
    throw std::invalid_argument("train_step: no micro-batches");
  const std::vector<Tensor>& params = optimizer.params();
  std::vector<Tensor> total(params.size());
  double loss_sum = 0.0;
  for (std::size_t i = 0; i < weights.size(); ++i) {
    const Tensor loss = micro_batch_loss(i);
    const float value = loss.item();
    if (!std::isfinite(value)) {
      throw std::invalid_argument("train_step: micro-batch " + std::to_string(i) + " has loss " +
                                  std::to_string(value) + "; no parameter was changed");
    }
    loss_sum += weights[i] * value;
    const std::vector<Tensor> g = grad({loss}, params, {}, false, /*allow_unused=*/true);
    GradModeGuard no_graph(false);
    for (std::size_t k = 0; k < params.size(); ++k) {
      const Tensor scaled = mul_scalar(g[k], static_cast<float>(weights[i]));
      total[k] = total[k].defined() ? add(total[k], scaled) : scaled;
    }
  }
  if (clip_norm > 0)
    clip_grad_norm(total, clip_norm);
  optimizer.step(total);
  return loss_sum;
}

}  // namespace ropes::nn
