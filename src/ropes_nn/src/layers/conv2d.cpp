#include "ropes_nn/layers/conv2d.hpp"

#include <stdexcept>
#include <string>

#include "layer_checks.hpp"

namespace ropes::nn {

Conv2d::Conv2d(std::int64_t in_channels, std::int64_t out_channels, std::int64_t kernel, int stride,
               Padding2d padding, bool bias)
    : stride_(stride), padding_(padding) {
  layer_checks::require_positive("Conv2d", "in_channels", in_channels);
  layer_checks::require_positive("Conv2d", "out_channels", out_channels);
  layer_checks::require_positive("Conv2d", "kernel", kernel);
  layer_checks::require_positive("Conv2d", "stride", stride);
  weight_ = register_parameter("weight", Shape{out_channels, in_channels, kernel, kernel},
                               "lecun_normal", in_channels * kernel * kernel);
  if (bias)
    bias_ = register_parameter("bias", Shape{out_channels}, "zeros");
}

Tensor Conv2d::forward(const Tensor& x) {
  // with a bias, conv2d adds it (in the product, where no graph is recorded)
  return bias_.defined() ? conv2d(x, weight_, bias_, stride_, padding_)
                         : conv2d(x, weight_, stride_, padding_);
}

}  // namespace ropes::nn
