#pragma once
/// @file layers/group_norm.hpp
/// GroupNorm: group normalisation with a learned per-channel scale and shift.
#include "ropes_nn/module.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {

/// group_norm with learned per-channel scale (gamma, "scale") and shift (beta, "bias").
/// `groups` defaults to min(32, channels), which must divide channels.
class GroupNorm : public Module {
 public:
  explicit GroupNorm(std::int64_t channels, int groups = 0, float eps = 1e-6f);
  int groups() const { return groups_; }
  /// relu(forward(x)), fused (group_norm_relu)
  Tensor with_relu(const Tensor& x);

 protected:
  Tensor forward(const Tensor& x) override;

 private:
  int groups_;
  float eps_;
  Tensor scale_, bias_;
};

}  // namespace ropes::nn
