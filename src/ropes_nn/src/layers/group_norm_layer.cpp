#include "ropes_nn/layers/group_norm.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

#include "layer_checks.hpp"

namespace ropes::nn {

GroupNorm::GroupNorm(std::int64_t channels, int groups, float eps) : eps_(eps) {
  layer_checks::require_positive("GroupNorm", "channels", channels);
  groups_ = groups > 0 ? groups : static_cast<int>(std::min<std::int64_t>(32, channels));
  if (channels % groups_ != 0) {
    throw std::invalid_argument("GroupNorm: " + std::to_string(groups_) + " groups for " +
                                std::to_string(channels) +
                                " channels; expected a divisor of the channel count");
  }
  scale_ = register_parameter("scale", Shape{channels}, "ones");
  bias_ = register_parameter("bias", Shape{channels}, "zeros");
}

Tensor GroupNorm::forward(const Tensor& x) {
  return group_norm(x, groups_, scale_, bias_, eps_);
}

Tensor GroupNorm::with_relu(const Tensor& x) {
  check_ready(1);
  return group_norm_relu(x, groups_, scale_, bias_, eps_);
}

}  // namespace ropes::nn
