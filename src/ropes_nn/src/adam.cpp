#include "ropes_nn/adam.hpp"

#include <algorithm>
#include <cmath>
#include <set>
#include <stdexcept>
#include <string>

#include "ropes_nn/ops.hpp"

namespace ropes::nn {

namespace {
void check_options(const AdamOptions& o, const char* function) {
  const std::string problem = o.problem();
  if (!problem.empty())
    throw std::invalid_argument(std::string(function) + ": " + problem);
}

std::vector<std::pair<std::string, Tensor>> numbered(const std::vector<Tensor>& params) {
  std::vector<std::pair<std::string, Tensor>> named;
  for (std::size_t i = 0; i < params.size(); ++i)
    named.emplace_back("param." + std::to_string(i), params[i]);
  return named;
}
}  // namespace

std::string AdamOptions::problem() const {
  if (lr > 0 && std::isfinite(lr) && beta1 >= 0 && beta1 < 1 && beta2 >= 0 && beta2 < 1 &&
      eps > 0 && weight_decay >= 0) {
    return "";
  }
  return "lr=" + std::to_string(lr) + " beta1=" + std::to_string(beta1) +
         " beta2=" + std::to_string(beta2) + " eps=" + std::to_string(eps) +
         " weight_decay=" + std::to_string(weight_decay) +
         "; expected lr > 0, betas in [0, 1), eps > 0, weight_decay >= 0";
}

Adam::Adam(std::vector<std::pair<std::string, Tensor>> params, AdamOptions options)
    : options_(options) {
  check_options(options_, "Adam");
  std::set<std::string> seen;
  for (std::size_t i = 0; i < params.size(); ++i) {
    const auto& [name, p] = params[i];
    if (name.empty() || !seen.insert(name).second) {
      throw std::invalid_argument("Adam: parameter " + std::to_string(i) + " is named '" + name +
                                  "'; expected a distinct, non-empty name");
    }
    if (!p.defined() || !p.requires_grad() || !p.is_leaf()) {
      throw std::invalid_argument("Adam: parameter '" + name +
                                  "' is not a leaf tensor that requires grad");
    }
    params_.push_back(p);
    names_.push_back(name);
    m_.emplace_back(static_cast<std::size_t>(p.numel()), 0.0f);
    v_.emplace_back(static_cast<std::size_t>(p.numel()), 0.0f);
    param_steps_.push_back(0);
  }
}

Adam::Adam(const std::vector<Tensor>& params, AdamOptions options)
    : Adam(numbered(params), options) {}

void Adam::set_lr(double lr) {
  if (!(lr >= 0) || !std::isfinite(lr)) {
    throw std::invalid_argument("Adam::set_lr: " + std::to_string(lr) +
                                "; expected a finite rate >= 0");
  }
  options_.lr = lr;
}

void Adam::set_options(const AdamOptions& options) {
  check_options(options, "Adam::set_options");
  options_ = options;
}

void Adam::update(std::size_t i, const Tensor& grad) {
  Tensor& p = params_[i];
  if (grad.shape() != p.shape()) {
    throw std::invalid_argument("Adam::step: gradient of '" + names_[i] + "' has shape " +
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
  // one loop without a branch for each case, so that it vectorises (with sqrt free of errno,
  // CMakeLists.txt): each lane does the scalar loop's operations, so the bits are the same
  const auto update_one = [&](std::int64_t k, float gk) {
    m[k] = b1 * m[k] + (1.0f - b1) * gk;
    v[k] = b2 * v[k] + (1.0f - b2) * gk * gk;
    w[k] -= step_size * m[k] / (std::sqrt(v[k]) / correction2_sqrt + eps);
  };
  const std::int64_t n = p.numel();
  if (wd != 0.0f) {
    for (std::int64_t k = 0; k < n; ++k)
      update_one(k, g[k] + wd * w[k]);
  } else {
    for (std::int64_t k = 0; k < n; ++k)
      update_one(k, g[k]);
  }
}

void Adam::set_param_steps(std::size_t i, std::int64_t steps) {
  if (steps < 0) {
    throw std::invalid_argument("Adam::set_param_steps: '" + names_.at(i) + "' gets " +
                                std::to_string(steps) + " steps; expected >= 0");
  }
  param_steps_.at(i) = steps;
}

void Adam::set_steps(std::int64_t steps) {
  if (steps < 0)
    throw std::invalid_argument("Adam::set_steps: " + std::to_string(steps) + "; expected >= 0");
  steps_ = steps;
  std::fill(param_steps_.begin(), param_steps_.end(), steps);
}

void Adam::step(const std::vector<Tensor>& grads) {
  if (grads.size() != params_.size()) {
    throw std::invalid_argument("Adam::step: " + std::to_string(grads.size()) + " gradients for " +
                                std::to_string(params_.size()) + " parameters");
  }
  for (std::size_t i = 0; i < params_.size(); ++i) {
    if (grads[i].defined() && grads[i].shape() != params_[i].shape()) {
      throw std::invalid_argument("Adam::step: gradient of '" + names_[i] + "' has shape " +
                                  grads[i].shape().str() + "; its parameter has " +
                                  params_[i].shape().str());
    }
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

}  // namespace ropes::nn
