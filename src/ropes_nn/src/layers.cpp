#include "ropes_nn/layers.hpp"

#include <algorithm>
#include <stdexcept>
#include <string>

namespace ropes::nn {

namespace {
void require_positive(const char* layer, const char* what, std::int64_t value) {
  if (value < 1) {
    throw std::invalid_argument(std::string(layer) + ": " + what + " is " + std::to_string(value) +
                                "; expected >= 1");
  }
}
Tensor add_channel_bias(const Tensor& y, const Tensor& bias) {
  return bias.defined() ? add(y, reshape(bias, Shape{1, bias.numel(), 1, 1})) : y;
}
}  // namespace

Conv2d::Conv2d(std::int64_t in_channels, std::int64_t out_channels, std::int64_t kernel, int stride,
               Padding2d padding, bool bias)
    : stride_(stride), padding_(padding) {
  require_positive("Conv2d", "in_channels", in_channels);
  require_positive("Conv2d", "out_channels", out_channels);
  require_positive("Conv2d", "kernel", kernel);
  require_positive("Conv2d", "stride", stride);
  weight_ = register_parameter("weight", Shape{out_channels, in_channels, kernel, kernel},
                               "lecun_normal", in_channels * kernel * kernel);
  if (bias)
    bias_ = register_parameter("bias", Shape{out_channels}, "zeros");
}

Tensor Conv2d::forward(const Tensor& x) {
  return add_channel_bias(conv2d(x, weight_, stride_, padding_), bias_);
}

ConvTranspose2d::ConvTranspose2d(std::int64_t in_channels, std::int64_t out_channels,
                                 std::int64_t kernel, int stride, Padding2d padding, bool bias)
    : stride_(stride), padding_(padding) {
  require_positive("ConvTranspose2d", "in_channels", in_channels);
  require_positive("ConvTranspose2d", "out_channels", out_channels);
  require_positive("ConvTranspose2d", "kernel", kernel);
  require_positive("ConvTranspose2d", "stride", stride);
  // Flax's ConvTranspose computes fan_in over the kernel's input channels and window
  weight_ = register_parameter("weight", Shape{in_channels, out_channels, kernel, kernel},
                               "lecun_normal", in_channels * kernel * kernel);
  if (bias)
    bias_ = register_parameter("bias", Shape{out_channels}, "zeros");
}

Tensor ConvTranspose2d::forward(const Tensor& x) {
  return add_channel_bias(conv_transpose2d(x, weight_, stride_, padding_), bias_);
}

GroupNorm::GroupNorm(std::int64_t channels, int groups, float eps) : eps_(eps) {
  require_positive("GroupNorm", "channels", channels);
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

Dense::Dense(std::int64_t in_features, std::int64_t out_features, bool bias) {
  require_positive("Dense", "in_features", in_features);
  require_positive("Dense", "out_features", out_features);
  weight_ =
      register_parameter("weight", Shape{in_features, out_features}, "lecun_normal", in_features);
  if (bias)
    bias_ = register_parameter("bias", Shape{out_features}, "zeros");
}

Tensor Dense::forward(const Tensor& x) {
  if (x.rank() != 2 || x.shape()[1] != weight_.shape()[0]) {
    throw std::invalid_argument("Dense: input " + x.shape().str() + "; expected [N, " +
                                std::to_string(weight_.shape()[0]) + "]");
  }
  const Tensor y = matmul(x, weight_);
  return bias_.defined() ? add(y, bias_) : y;
}

ResBlockGN::ResBlockGN(std::int64_t channels, int groups) {
  norm1_ = register_module("norm1", std::make_shared<GroupNorm>(channels, groups));
  conv1_ = register_module("conv1", std::make_shared<Conv2d>(channels, channels, 3));
  norm2_ = register_module("norm2", std::make_shared<GroupNorm>(channels, groups));
  conv2_ = register_module("conv2", std::make_shared<Conv2d>(channels, channels, 3));
}

Tensor ResBlockGN::forward(const Tensor& x) {
  const Tensor h = (*conv1_)(relu((*norm1_)(x)));
  return add(x, (*conv2_)(relu((*norm2_)(h))));
}

}  // namespace ropes::nn
