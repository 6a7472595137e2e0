#pragma once
/// @file gradcheck.hpp
/// A generic gradient checker: compares ropes::nn::grad() with central finite differences.
/// Every operation's and module's test calls it; tests of the ops on the AE2 path also call
/// it on the gradient function itself (check_second_gradients).

#include <functional>
#include <string>
#include <vector>

#include "ropes_nn/tensor.hpp"

namespace ropes::nn {

/// A differentiable function of several tensors.
using TensorFunction = std::function<Tensor(const std::vector<Tensor>& inputs)>;

struct GradCheckOptions {
  double step = 1e-2;           ///< finite-difference step (float32 values: not too small)
  double abs_tolerance = 1e-3;  ///< |analytic - numeric| <= abs + rel * |numeric| passes
  double rel_tolerance = 1e-2;
  std::uint64_t seed = 1234;  ///< seeds the random projection of a non-scalar output
};

struct GradCheckResult {
  bool ok = true;
  double max_abs_error = 0.0;
  std::string report;  ///< the worst entry, or every failing entry (at most 10)
};

/// Checks d L / d inputs for L = <f(inputs), w>, w a fixed random tensor (seeded), against
/// central differences (L(x + h) - L(x - h)) / 2h computed entry by entry, the projection
/// summed in double. Inputs must be leaves; they are marked requires_grad and restored.
/// Cost: 2 * (total input elements) evaluations of f.
GradCheckResult check_gradients(const TensorFunction& f, const std::vector<Tensor>& inputs,
                                const GradCheckOptions& options = {});

/// Checks the gradients of the gradient: applies check_gradients to
/// g(inputs) = concat of d<f(inputs), w>/d inputs computed with create_graph = true, i.e.
/// Hessian-vector products of f against finite differences of its first derivatives.
GradCheckResult check_second_gradients(const TensorFunction& f, const std::vector<Tensor>& inputs,
                                       const GradCheckOptions& options = {});

class Module;

/// Checks a module: d<module(x), w>/dx and d<module(x), w>/d(each parameter) against
/// central differences, perturbing x and the parameters' storage in place (restored after).
/// The report names the parameter by its dotted path.
GradCheckResult check_module_gradients(Module& module, const Tensor& x,
                                       const GradCheckOptions& options = {});

}  // namespace ropes::nn
