#pragma once
/// @file module.hpp
/// Module: a network piece with named parameters and child modules; Sequential and ReLU.
///
/// Parameters are named by their path: a Conv2d registered as "conv1" inside a ResBlockGN
/// registered as "block0" inside "stage1" of "encoder" owns "encoder.stage1.block0.conv1.weight".
/// Those names are the keys of saved weights (.safetensors) and of optimiser state.
///
/// Misuse is refused rather than silently wrong:
///   - a module is neither copyable nor movable: a copy would share its parameter tensors
///     with the original (two "independent" networks training the same weights). Hold
///     modules where they are built, or by std::shared_ptr.
///   - calling a module whose parameters were never initialised (initialize(), or weights
///     loaded with load_module / load_checkpoint) throws std::logic_error naming the first
///     such parameter.
///   - modules with several inputs (a decoder fed a latent and a code, a classifier fed two
///     cameras' codes) derive from MultiInputModule; calling one with the wrong number of
///     inputs throws std::invalid_argument.
///
/// Two modules with the same local parameter names (one classifier per joint, each built by
/// the same code) initialised with the same seed get the same weights: that is what "the
/// values depend only on the seed and the name" means. Give each its own seed, or the same
/// seed and its own scope (the scope joins the name in the stream number):
///   for (int j = 0; j < joints; ++j) ldr[j]->initialize(seed, "ldr" + std::to_string(j));

#include <cstdint>
#include <memory>
#include <string>
#include <utility>
#include <vector>

#include "ropes_nn/tensor.hpp"

namespace ropes::nn {

class Module {
 public:
  Module() = default;
  virtual ~Module() = default;
  Module(const Module&) = delete;
  Module& operator=(const Module&) = delete;
  Module(Module&&) = delete;
  Module& operator=(Module&&) = delete;

  /// The module applied to `x`. Throws std::logic_error naming the first parameter (dotted
  /// path below this module) that was never initialised, and std::invalid_argument when the
  /// module takes another number of inputs. The check walks the parameters once; later calls
  /// cost nothing.
  Tensor operator()(const Tensor& x);
  /// The module applied to several inputs (a MultiInputModule; a single-input module takes a
  /// list of one). Same checks.
  Tensor operator()(const std::vector<Tensor>& inputs);
  /// How many tensors forward takes (1 unless a MultiInputModule says otherwise).
  virtual std::size_t input_count() const { return 1; }

  /// Every parameter of this module and its children, depth first in registration order,
  /// with its dotted path.
  std::vector<std::pair<std::string, Tensor>> named_parameters() const;
  std::vector<Tensor> parameters() const;
  /// Number of scalar parameters.
  std::int64_t parameter_count() const;

  /// Initialises every parameter from `seed`: each one draws from its own Philox stream,
  /// numbered by a hash (FNV-1a 64) of its full name, so a parameter's initial values depend
  /// only on the seed and its name, not on what else the network holds. Kernels get
  /// "lecun_normal", biases and GroupNorm's beta zeros, GroupNorm's gamma ones.
  void initialize(std::uint64_t seed);
  /// The same with the stream numbered by a hash of "<scope>/<full name>": modules built by
  /// the same code (same names) get independent values under one seed. An empty scope is
  /// initialize(seed).
  void initialize(std::uint64_t seed, const std::string& scope);

  /// Declares parameter `name` (dotted path, as named_parameters) set by the caller, e.g.
  /// after writing its values from a file. Throws std::invalid_argument for an unknown name.
  void mark_initialized(const std::string& name);
  /// The dotted names of the parameters that were never initialised, in named_parameters()
  /// order.
  std::vector<std::string> uninitialized_parameters() const;

 protected:
  /// What the module computes; called by operator() after its checks. Children are called
  /// through their operator() too.
  virtual Tensor forward(const Tensor& x) = 0;
  /// Several inputs: a single-input module gets forward(inputs[0]); MultiInputModule
  /// overrides this.
  virtual Tensor forward_inputs(const std::vector<Tensor>& inputs) { return forward(inputs[0]); }

  /// Adds a parameter (marked requires_grad, not yet initialised) named `name` within this
  /// module.
  Tensor register_parameter(const std::string& name, const Shape& shape, const std::string& init,
                            std::int64_t fan_in = 0);
  /// What operator() checks before forward: the input count, and (once) that every
  /// parameter was initialised; for a module's other entry points (GroupNorm::with_relu).
  void check_ready(std::size_t inputs);
  /// Adds a child; its parameters are named "<name>.<their name>".
  template <typename M>
  std::shared_ptr<M> register_module(const std::string& name, std::shared_ptr<M> module) {
    add_child(name, module);
    return module;
  }

 private:
  struct Parameter {
    std::string name;
    Tensor value;
    std::string init;  // "lecun_normal", "zeros" or "ones"
    std::int64_t fan_in;
    bool initialized = false;
  };
  void add_child(const std::string& name, std::shared_ptr<Module> module);
  void initialize_tree(std::uint64_t seed, const std::string& scope, const std::string& prefix);
  bool mark(const std::string& name);

  std::vector<Parameter> parameters_;
  std::vector<std::pair<std::string, std::shared_ptr<Module>>> children_;
  bool verified_ = false;  // every parameter below was initialised when last checked
};

/// A module of several inputs: implement forward_inputs(inputs), which is called with
/// exactly input_count() tensors.
class MultiInputModule : public Module {
 public:
  /// `inputs` >= 1 (std::invalid_argument otherwise).
  explicit MultiInputModule(std::size_t inputs);
  std::size_t input_count() const final { return inputs_; }

 protected:
  Tensor forward_inputs(const std::vector<Tensor>& inputs) override = 0;

 private:
  Tensor forward(const Tensor& x) final { return forward_inputs({x}); }
  std::size_t inputs_;
};

/// Applies its children in order; they are named "0", "1", ... unless given names.
class Sequential : public Module {
 public:
  Sequential() = default;
  explicit Sequential(std::vector<std::shared_ptr<Module>> modules);
  /// Appends `module` (a single-input module), named `name` (default: its position).
  Sequential& add(std::shared_ptr<Module> module, std::string name = "");
  std::size_t size() const { return modules_.size(); }

 protected:
  Tensor forward(const Tensor& x) override;

 private:
  std::vector<std::shared_ptr<Module>> modules_;
};

/// max(x, 0).
class ReLU : public Module {
 protected:
  Tensor forward(const Tensor& x) override;
};

/// FNV-1a 64-bit hash of `text`: the stream number of a named parameter's initialiser.
std::uint64_t fnv1a64(const std::string& text);

}  // namespace ropes::nn
