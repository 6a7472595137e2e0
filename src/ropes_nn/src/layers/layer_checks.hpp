#pragma once
// What the layers' constructors and forward passes share (private to ropes_nn).
#include <cstdint>
#include <stdexcept>
#include <string>

#include "ropes_nn/ops.hpp"
#include "ropes_nn/tensor.hpp"

namespace ropes::nn::layer_checks {

// a layer's size argument below 1: std::invalid_argument naming the layer and the argument
inline void require_positive(const char* layer, const char* what, std::int64_t value) {
  if (value < 1) {
    throw std::invalid_argument(std::string(layer) + ": " + what + " is " + std::to_string(value) +
                                "; expected >= 1");
  }
}

// y + bias over the channels of an NCHW tensor; y itself without a bias
inline Tensor add_channel_bias(const Tensor& y, const Tensor& bias) {
  return bias.defined() ? add(y, reshape(bias, Shape{1, bias.numel(), 1, 1})) : y;
}

}  // namespace ropes::nn::layer_checks
