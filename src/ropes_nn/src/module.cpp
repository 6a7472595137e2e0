#include "ropes_nn/module.hpp"

#include <algorithm>
#include <cmath>
#include <stdexcept>

#include "ropes_core/philox.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {

namespace {
// Flax's lecun_normal: variance_scaling(1, "fan_in", "truncated_normal"); the truncated
// normal on [-2, 2] has std 0.87962566103423978, divided out so the result has 1 / fan_in
constexpr double kTruncatedStd = 0.87962566103423978;
}  // namespace

std::uint64_t fnv1a64(const std::string& text) {
  std::uint64_t h = 0xcbf29ce484222325ull;
  for (unsigned char c : text) {
    h ^= c;
    h *= 0x100000001b3ull;
  }
  return h;
}

Tensor Module::register_parameter(const std::string& name, const Shape& shape,
                                  const std::string& init, std::int64_t fan_in) {
  if (init != "lecun_normal" && init != "zeros" && init != "ones") {
    throw std::invalid_argument("Module::register_parameter: init '" + init + "' of '" + name +
                                "'; expected lecun_normal, zeros or ones");
  }
  if (init == "lecun_normal" && fan_in <= 0) {
    throw std::invalid_argument("Module::register_parameter: '" + name +
                                "' is lecun_normal but has fan_in " + std::to_string(fan_in));
  }
  Tensor t = Tensor::full(shape, init == "ones" ? 1.0f : 0.0f, true);
  parameters_.push_back({name, t, init, fan_in, false});
  verified_ = false;
  return t;
}

void Module::add_child(const std::string& name, std::shared_ptr<Module> module) {
  if (!module)
    throw std::invalid_argument("Module::register_module: '" + name + "' is null");
  children_.emplace_back(name, std::move(module));
  verified_ = false;
}

std::vector<std::pair<std::string, Tensor>> Module::named_parameters() const {
  std::vector<std::pair<std::string, Tensor>> result;
  for (const Parameter& p : parameters_)
    result.emplace_back(p.name, p.value);
  for (const auto& [child_name, child] : children_) {
    for (auto& [name, t] : child->named_parameters()) {
      result.emplace_back(child_name + "." + name, t);
    }
  }
  return result;
}

std::vector<Tensor> Module::parameters() const {
  std::vector<Tensor> result;
  for (auto& [name, t] : named_parameters())
    result.push_back(t);
  return result;
}

std::int64_t Module::parameter_count() const {
  std::int64_t n = 0;
  for (const Tensor& t : parameters())
    n += t.numel();
  return n;
}

void Module::initialize(std::uint64_t seed) {
  initialize_tree(seed, "", "");
}

void Module::initialize(std::uint64_t seed, const std::string& scope) {
  initialize_tree(seed, scope, "");
}

// own parameters, then children under their prefixes (names as named_parameters gives them)
void Module::initialize_tree(std::uint64_t seed, const std::string& scope,
                             const std::string& prefix) {
  for (Parameter& p : parameters_) {
    const std::string full = prefix + p.name;
    float* v = p.value.mutable_data();
    const std::int64_t n = p.value.numel();
    if (p.init == "lecun_normal") {
      core::PhiloxStream rng(seed, fnv1a64(scope.empty() ? full : scope + "/" + full));
      const double scale = std::sqrt(1.0 / static_cast<double>(p.fan_in)) / kTruncatedStd;
      for (std::int64_t i = 0; i < n; ++i)
        v[i] = static_cast<float>(scale * rng.truncated_normal(-2.0, 2.0));
    } else {
      std::fill(v, v + n, p.init == "ones" ? 1.0f : 0.0f);
    }
    p.initialized = true;
  }
  for (auto& [name, child] : children_)
    child->initialize_tree(seed, scope, prefix + name + ".");
}

bool Module::mark(const std::string& name) {
  for (Parameter& p : parameters_) {
    if (p.name == name) {
      p.initialized = true;
      return true;
    }
  }
  for (auto& [child_name, child] : children_) {
    if (name.size() > child_name.size() && name.compare(0, child_name.size(), child_name) == 0 &&
        name[child_name.size()] == '.' && child->mark(name.substr(child_name.size() + 1))) {
      return true;
    }
  }
  return false;
}

void Module::mark_initialized(const std::string& name) {
  if (!mark(name)) {
    throw std::invalid_argument("Module::mark_initialized: the module has no parameter '" + name +
                                "'");
  }
}

std::vector<std::string> Module::uninitialized_parameters() const {
  std::vector<std::string> names;
  struct Walker {
    static void run(const Module& m, const std::string& prefix, std::vector<std::string>* out) {
      for (const Parameter& p : m.parameters_) {
        if (!p.initialized)
          out->push_back(prefix + p.name);
      }
      for (const auto& [name, child] : m.children_)
        run(*child, prefix + name + ".", out);
    }
  };
  Walker::run(*this, "", &names);
  return names;
}

void Module::check_ready(std::size_t inputs) {
  if (inputs != input_count()) {
    throw std::invalid_argument("Module: called with " + std::to_string(inputs) +
                                " input(s); this module takes " + std::to_string(input_count()));
  }
  if (verified_)
    return;
  const std::vector<std::string> missing = uninitialized_parameters();
  if (!missing.empty()) {
    throw std::logic_error("Module: parameter '" + missing.front() +
                           "' was never initialised; call initialize(seed) or load weights "
                           "(load_module, load_checkpoint) before calling the module");
  }
  verified_ = true;
}

Tensor Module::operator()(const Tensor& x) {
  check_ready(1);
  return forward(x);
}

Tensor Module::operator()(const std::vector<Tensor>& inputs) {
  check_ready(inputs.size());
  return forward_inputs(inputs);
}

MultiInputModule::MultiInputModule(std::size_t inputs) : inputs_(inputs) {
  if (inputs < 1)
    throw std::invalid_argument("MultiInputModule: 0 inputs; expected at least 1");
}

Sequential::Sequential(std::vector<std::shared_ptr<Module>> modules) {
  for (auto& m : modules)
    add(std::move(m));
}

Sequential& Sequential::add(std::shared_ptr<Module> module, std::string name) {
  if (!module)
    throw std::invalid_argument("Sequential::add: null module");
  if (module->input_count() != 1) {
    throw std::invalid_argument("Sequential::add: the module takes " +
                                std::to_string(module->input_count()) +
                                " inputs; a Sequential chains single-input modules");
  }
  if (name.empty())
    name = std::to_string(modules_.size());
  register_module(name, module);
  modules_.push_back(std::move(module));
  return *this;
}

Tensor Sequential::forward(const Tensor& x) {
  Tensor y = x;
  for (auto& m : modules_)
    y = (*m)(y);
  return y;
}

Tensor ReLU::forward(const Tensor& x) {
  return relu(x);
}

}  // namespace ropes::nn
