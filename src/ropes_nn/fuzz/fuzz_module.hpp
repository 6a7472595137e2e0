#pragma once
// The small network the checkpoint harness loads into, and the corpus maker saves.
#include <memory>

#include "ropes_nn/layers.hpp"
#include "ropes_nn/module.hpp"

namespace ropes::nn::fuzz {

inline std::shared_ptr<Sequential> fuzz_module() {
  auto net = std::make_shared<Sequential>();
  net->add(std::make_shared<Conv2d>(1, 2, 3, 2), "conv");
  net->add(std::make_shared<ReLU>());
  net->add(std::make_shared<Dense>(8, 3), "head");
  return net;
}

}  // namespace ropes::nn::fuzz
