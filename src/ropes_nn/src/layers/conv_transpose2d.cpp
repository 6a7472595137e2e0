#include "ropes_nn/layers/conv_transpose2d.hpp"

#include <stdexcept>
#include <string>

#include "layer_checks.hpp"

namespace ropes::nn {

ConvTranspose2d::ConvTranspose2d(std::int64_t in_channels, std::int64_t out_channels,
                                 std::int64_t kernel, int stride, Padding2d padding, bool bias)
    : stride_(stride), padding_(padding) {
  layer_checks::require_positive("ConvTranspose2d", "in_channels", in_channels);
  layer_checks::require_positive("ConvTranspose2d", "out_channels", out_channels);
  layer_checks::require_positive("ConvTranspose2d", "kernel", kernel);
  layer_checks::require_positive("ConvTranspose2d", "stride", stride);
  // Flax's ConvTranspose computes fan_in over the kernel's input channels and window
  weight_ = register_parameter("weight", Shape{in_channels, out_channels, kernel, kernel},
                               "lecun_normal", in_channels * kernel * kernel);
  if (bias)
    bias_ = register_parameter("bias", Shape{out_channels}, "zeros");
}

Tensor ConvTranspose2d::forward(const Tensor& x) {
  return layer_checks::add_channel_bias(conv_transpose2d(x, weight_, stride_, padding_), bias_);
}

}  // namespace ropes::nn
