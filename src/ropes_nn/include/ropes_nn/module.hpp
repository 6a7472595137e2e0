#pragma once
/// @file module.hpp
/// Module: a network piece with named parameters and child modules; Sequential and ReLU.
///
/// Parameters are named by their path: a Conv2d registered as "conv1" inside a ResBlockGN
/// registered as "block0" inside "stage1" of "encoder" owns "encoder.stage1.block0.conv1.weight".
/// Those names are the keys of saved weights (.safetensors).

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "ropes_nn/tensor.hpp"

namespace ropes::nn {

class Module {
 public:
  virtual ~Module() = default;

  /// The module applied to `x`.
  virtual Tensor forward(const Tensor& x) = 0;
  Tensor operator()(const Tensor& x) { return forward(x); }

  /// Every parameter of this module and its children, depth first in registration order,
  /// with its dotted path.
  std::vector<std::pair<std::string, Tensor>> named_parameters() const;
  std::vector<Tensor> parameters() const;
  /// Number of scalar parameters.
  std::int64_t parameter_count() const;

  /// Initialises every parameter from `seed`: each one draws from its own Philox stream,
  /// numbered by a hash (FNV-1a 64) of its full name, so a parameter's initial values depend
  /// only on the seed and its name, not on what else the network holds. Kernels get
  /// init_kind() "lecun_normal", biases and GroupNorm's beta zeros, GroupNorm's gamma ones.
  void initialize(std::uint64_t seed);

 protected:
  /// Adds a parameter (marked requires_grad) named `name` within this module.
  Tensor register_parameter(const std::string& name, const Shape& shape, const std::string& init,
                            std::int64_t fan_in = 0);
  /// Adds a child; its parameters are named "<name>.<their name>".
  template <typename M>
  std::shared_ptr<M> register_module(const std::string& name, std::shared_ptr<M> module) {
    children_.emplace_back(name, module);
    return module;
  }

 private:
  struct Parameter {
    std::string name;
    Tensor value;
    std::string init;  // "lecun_normal", "zeros" or "ones"
    std::int64_t fan_in;
  };
  std::vector<Parameter> parameters_;
  std::vector<std::pair<std::string, std::shared_ptr<Module>>> children_;
};

/// Applies its children in order; they are named "0", "1", ... unless given names.
class Sequential : public Module {
 public:
  Sequential() = default;
  explicit Sequential(std::vector<std::shared_ptr<Module>> modules);
  /// Appends `module`, named `name` (default: its position).
  Sequential& add(std::shared_ptr<Module> module, std::string name = "");
  Tensor forward(const Tensor& x) override;
  std::size_t size() const { return modules_.size(); }

 private:
  std::vector<std::shared_ptr<Module>> modules_;
};

/// max(x, 0).
class ReLU : public Module {
 public:
  Tensor forward(const Tensor& x) override;
};

/// FNV-1a 64-bit hash of `text`: the stream number of a named parameter's initialiser.
std::uint64_t fnv1a64(const std::string& text);

}  // namespace ropes::nn
