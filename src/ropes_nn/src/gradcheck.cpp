#include "ropes_nn/gradcheck.hpp"

#include <algorithm>
#include <cmath>
#include <functional>
#include <sstream>
#include <string>

#include "ropes_core/philox.hpp"
#include "ropes_nn/module.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {

namespace {

// <y, w> in double
double project(const Tensor& y, const std::vector<float>& w) {
  double s = 0.0;
  const float* p = y.data();
  for (std::size_t i = 0; i < w.size(); ++i)
    s += static_cast<double>(p[i]) * w[i];
  return s;
}

std::vector<float> projection_weights(const Shape& shape, std::uint64_t seed) {
  core::PhiloxStream rng(seed, 0);
  std::vector<float> w(static_cast<std::size_t>(shape.numel()));
  for (float& v : w)
    v = static_cast<float>(rng.normal());
  return w;
}

// Central differences of `evaluate` (the projected output) in every entry of `tensors`,
// perturbed in place and restored, compared with `analytic`; `names` label the report.
GradCheckResult compare_with_finite_differences(std::vector<Tensor>& tensors,
                                                const std::vector<std::string>& names,
                                                const std::vector<Tensor>& analytic,
                                                const std::function<double()>& evaluate,
                                                const GradCheckOptions& options) {
  GradCheckResult result;
  int failures = 0;
  std::ostringstream report;
  for (std::size_t k = 0; k < tensors.size(); ++k) {
    float* values = tensors[k].mutable_data();
    const float* a = analytic[k].data();
    for (std::int64_t i = 0; i < tensors[k].numel(); ++i) {
      const float saved = values[i];
      const float up_value = saved + static_cast<float>(options.step);
      const float down_value = saved - static_cast<float>(options.step);
      values[i] = up_value;
      const double up = evaluate();
      values[i] = down_value;
      const double down = evaluate();
      values[i] = saved;
      // divide by the step the float values actually took
      const double numeric = (up - down) / (static_cast<double>(up_value) - down_value);
      const double error = std::abs(a[i] - numeric);
      result.max_abs_error = std::max(result.max_abs_error, error);
      if (!(error <= options.abs_tolerance + options.rel_tolerance * std::abs(numeric))) {
        result.ok = false;
        if (failures++ < 10) {
          report << names[k] << " " << tensors[k].shape().str() << " element " << i << ": analytic "
                 << a[i] << ", numeric " << numeric << "\n";
        }
      }
    }
  }
  if (result.ok)
    report << "max |analytic - numeric| = " << result.max_abs_error;
  result.report = report.str();
  return result;
}

}  // namespace

GradCheckResult check_gradients(const TensorFunction& f, const std::vector<Tensor>& inputs,
                                const GradCheckOptions& options) {
  // fresh leaves holding the inputs' values
  std::vector<Tensor> leaves;
  for (const Tensor& x : inputs)
    leaves.push_back(x.detach().set_requires_grad(true));

  // analytic: grad of <f, w>
  const Tensor y = f(leaves);
  const std::vector<float> w = projection_weights(y.shape(), options.seed);
  const Tensor weights(y.shape(), w);
  const std::vector<Tensor> analytic = grad({y}, leaves, {weights}, false, true);

  // numeric (grad mode stays on: f may itself take gradients, as check_second_gradients' f does)
  std::vector<std::string> names;
  for (std::size_t k = 0; k < leaves.size(); ++k)
    names.push_back("input " + std::to_string(k));
  return compare_with_finite_differences(
      leaves, names, analytic, [&] { return project(f(leaves), w); }, options);
}

GradCheckResult check_second_gradients(const TensorFunction& f, const std::vector<Tensor>& inputs,
                                       const GradCheckOptions& options) {
  const TensorFunction first_derivatives = [&f, &options](const std::vector<Tensor>& xs) {
    const Tensor y = f(xs);
    const Tensor w(y.shape(), projection_weights(y.shape(), options.seed + 1));
    const std::vector<Tensor> g = grad({y}, xs, {w}, /*create_graph=*/true, /*allow_unused=*/true);
    std::vector<Tensor> flat;
    for (const Tensor& t : g)
      flat.push_back(reshape(t, Shape{t.numel()}));
    return flat.size() == 1 ? flat[0] : concat(flat, 0);
  };
  return check_gradients(first_derivatives, inputs, options);
}

GradCheckResult check_module_gradients(Module& module, const Tensor& x,
                                       const GradCheckOptions& options) {
  const auto named = module.named_parameters();
  std::vector<Tensor> wrt = {x.detach().set_requires_grad(true)};
  std::vector<std::string> names = {"input"};
  for (const auto& [name, p] : named) {
    wrt.push_back(p);
    names.push_back(name);
  }
  const Tensor y = module(wrt[0]);
  const std::vector<float> w = projection_weights(y.shape(), options.seed);
  const std::vector<Tensor> analytic =
      grad({y}, wrt, {Tensor(y.shape(), w)}, false, /*allow_unused=*/true);

  return compare_with_finite_differences(
      wrt, names, analytic, [&] { return project(module(wrt[0]), w); }, options);
}

}  // namespace ropes::nn
