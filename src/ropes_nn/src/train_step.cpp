#include "ropes_nn/train_step.hpp"

#include <Eigen/Core>

#include <cmath>
#include <stdexcept>
#include <string>

#include "ropes_nn/ops.hpp"

namespace ropes::nn {

namespace {

[[noreturn]] void refuse(const std::string& what) {
  throw std::invalid_argument("train_step: " + what + "; no parameter was changed");
}

// statistic k's shape without dim 0: the shape of its mean
Shape trailing(const Shape& s) {
  std::vector<std::int64_t> dims = s.dims();
  dims.erase(dims.begin());
  return Shape(dims);
}

// checks micro-batch i's statistics against the first micro-batch's (`expected`, empty for
// the first) and returns its sample count
std::int64_t check_statistics(const std::vector<Tensor>& stats, std::size_t i,
                              std::vector<Shape>* expected) {
  const std::string where = "micro-batch " + std::to_string(i);
  if (stats.empty())
    refuse(where + " returned no statistics; expected at least one [samples, ...] tensor");
  if (!expected->empty() && stats.size() != expected->size()) {
    refuse(where + " returned " + std::to_string(stats.size()) + " statistics; micro-batch 0 " +
           "returned " + std::to_string(expected->size()));
  }
  std::int64_t n = -1;
  for (std::size_t k = 0; k < stats.size(); ++k) {
    const std::string what = where + ", statistic " + std::to_string(k);
    if (!stats[k].defined())
      refuse(what + " is undefined");
    const Shape& s = stats[k].shape();
    if (s.rank() < 1)
      refuse(what + " has shape " + s.str() + "; expected [samples, ...]");
    if (n >= 0 && s[0] != n) {
      refuse(what + " has " + std::to_string(s[0]) + " samples (shape " + s.str() +
             "); statistic 0 has " + std::to_string(n));
    }
    n = s[0];
    if (expected->size() > k && trailing(s) != (*expected)[k]) {
      refuse(what + " has shape " + s.str() + "; expected [samples] + " + (*expected)[k].str() +
             ", as in micro-batch 0");
    }
  }
  if (expected->empty()) {
    for (const Tensor& t : stats)
      expected->push_back(trailing(t.shape()));
  }
  return n;
}

double checked_loss_value(const Tensor& loss) {
  if (!loss.defined() || loss.numel() != 1) {
    refuse("the outer function returned " +
           (loss.defined() ? "shape " + loss.shape().str() : std::string("an undefined tensor")) +
           "; expected one element");
  }
  const float value = loss.item();
  if (!std::isfinite(value))
    refuse("the loss is " + (std::isnan(value) ? std::string("nan") : std::to_string(value)));
  return value;
}

// adds the row-sums of each statistic to `sums` (double, in sample order)
void add_row_sums(const std::vector<Tensor>& stats, std::vector<std::vector<double>>* sums) {
  if (sums->empty()) {
    for (const Tensor& t : stats)
      sums->emplace_back(static_cast<std::size_t>(trailing(t.shape()).numel()), 0.0);
  }
  for (std::size_t k = 0; k < stats.size(); ++k) {
    std::vector<double>& acc = (*sums)[k];
    const float* p = stats[k].data();
    const std::int64_t rows = stats[k].shape()[0];
    const auto width = static_cast<std::int64_t>(acc.size());
    for (std::int64_t r = 0; r < rows; ++r) {
      for (std::int64_t j = 0; j < width; ++j)
        acc[static_cast<std::size_t>(j)] += p[r * width + j];
    }
  }
}

std::vector<Tensor> means_of(const std::vector<std::vector<double>>& sums,
                             const std::vector<Shape>& shapes, std::int64_t samples,
                             bool requires_grad) {
  std::vector<Tensor> means;
  for (std::size_t k = 0; k < sums.size(); ++k) {
    std::vector<float> v(sums[k].size());
    for (std::size_t j = 0; j < v.size(); ++j)
      v[j] = static_cast<float>(sums[k][j] / static_cast<double>(samples));
    means.emplace_back(shapes[k], v, requires_grad);
  }
  return means;
}

// the outer derivative dF/dm_k at `means`, divided by the sample count
std::vector<Tensor> seeds_per_sample(const BatchLoss& loss, const std::vector<Tensor>& means,
                                     std::int64_t samples, double* value) {
  const Tensor f = loss.outer(means);
  *value = checked_loss_value(f);
  std::vector<Tensor> g = grad({f}, means, {}, false, /*allow_unused=*/true);
  for (Tensor& t : g) {
    float* p = t.mutable_data();
    for (std::int64_t j = 0; j < t.numel(); ++j)
      p[j] = static_cast<float>(static_cast<double>(p[j]) / static_cast<double>(samples));
  }
  return g;
}

// micro-batch gradients: a backward pass of the statistics seeded with the outer derivative
std::vector<Tensor> seeded_gradients(const std::vector<Tensor>& stats,
                                     const std::vector<Tensor>& seeds,
                                     const std::vector<Tensor>& params) {
  std::vector<Tensor> grad_outputs;
  for (std::size_t k = 0; k < stats.size(); ++k) {
    std::vector<std::int64_t> dims = seeds[k].shape().dims();
    dims.insert(dims.begin(), 1);
    GradModeGuard no_graph(false);
    grad_outputs.push_back(broadcast_to(reshape(seeds[k], Shape(dims)), stats[k].shape()));
  }
  return grad(stats, params, grad_outputs, false, /*allow_unused=*/true);
}

void accumulate(std::vector<Tensor>* total, const std::vector<Tensor>& g) {
  GradModeGuard no_graph(false);
  for (std::size_t p = 0; p < g.size(); ++p)
    (*total)[p] = (*total)[p].defined() ? add((*total)[p], g[p]) : g[p];
}

std::vector<std::vector<float>> values_of(const std::vector<Tensor>& means) {
  std::vector<std::vector<float>> out;
  for (const Tensor& m : means)
    out.push_back(m.to_vector());
  return out;
}

}  // namespace

BatchLoss mean_loss(std::function<Tensor(std::size_t i)> per_sample) {
  BatchLoss loss;
  loss.statistics = [per_sample = std::move(per_sample)](std::size_t i, bool) {
    return std::vector<Tensor>{per_sample(i)};
  };
  loss.outer = [](const std::vector<Tensor>& means) { return means[0]; };
  loss.outer_is_affine = true;
  return loss;
}

BatchGradient batch_gradient(const std::vector<Tensor>& params, const BatchLoss& loss,
                             std::size_t micro_batches) {
  if (micro_batches == 0)
    refuse("0 micro-batches; expected at least 1");
  if (!loss.statistics || !loss.outer)
    refuse("the BatchLoss lacks its statistics or outer function");
  const std::size_t parts = micro_batches;
  BatchGradient result;
  std::vector<Tensor>& total = result.grads;
  total.resize(params.size());
  std::vector<Shape> shapes;

  if (parts == 1) {
    // one micro-batch: differentiate F(mean of the statistics) directly
    const std::vector<Tensor> stats = loss.statistics(0, true);
    result.samples = check_statistics(stats, 0, &shapes);
    if (result.samples == 0)
      refuse("the batch has 0 samples");
    std::vector<Tensor> means;
    for (const Tensor& s : stats)
      means.push_back(mean(s, {0}));
    const Tensor f = loss.outer(means);
    result.loss = checked_loss_value(f);
    result.means = values_of(means);
    total = grad({f}, params, {}, false, /*allow_unused=*/true);
  } else if (!loss.outer_is_affine) {
    // phase 1: the batch means, then the outer derivative there
    std::vector<std::vector<double>> sums;
    std::vector<std::int64_t> counts;
    for (std::size_t i = 0; i < parts; ++i) {
      const std::vector<Tensor> stats = loss.statistics(i, false);
      counts.push_back(check_statistics(stats, i, &shapes));
      result.samples += counts.back();
      add_row_sums(stats, &sums);
    }
    if (result.samples == 0)
      refuse("the batch has 0 samples");
    const std::vector<Tensor> means = means_of(sums, shapes, result.samples, true);
    const std::vector<Tensor> seeds = seeds_per_sample(loss, means, result.samples, &result.loss);
    result.means = values_of(means);
    // phase 2: each micro-batch's backward pass, seeded with the outer derivative
    for (std::size_t i = 0; i < parts; ++i) {
      const std::vector<Tensor> stats = loss.statistics(i, true);
      if (check_statistics(stats, i, &shapes) != counts[i]) {
        refuse("micro-batch " + std::to_string(i) + " has " + std::to_string(stats[0].shape()[0]) +
               " samples now and had " + std::to_string(counts[i]) +
               " in the statistics pass (statistics must be a " +
               "pure function of the micro-batch)");
      }
      accumulate(&total, seeded_gradients(stats, seeds, params));
    }
  } else {
    // affine F: its derivative is the same everywhere (taken at zero means), one pass
    std::vector<std::vector<double>> sums;
    std::vector<Tensor> seeds;
    for (std::size_t i = 0; i < parts; ++i) {
      const std::vector<Tensor> stats = loss.statistics(i, true);
      const std::int64_t n = check_statistics(stats, i, &shapes);
      if (seeds.empty()) {
        std::vector<Tensor> zeros;
        for (const Shape& s : shapes)
          zeros.push_back(Tensor::zeros(s, true));
        double ignored = 0;
        seeds = seeds_per_sample(loss, zeros, 1, &ignored);
      }
      result.samples += n;
      add_row_sums(stats, &sums);
      accumulate(&total, seeded_gradients(stats, seeds, params));
    }
    if (result.samples == 0)
      refuse("the batch has 0 samples");
    // the seeds were per sample of a batch of one: divide by the real count
    {
      GradModeGuard no_graph(false);
      for (Tensor& t : total)
        t = mul_scalar(t, static_cast<float>(1.0 / static_cast<double>(result.samples)));
    }
    const std::vector<Tensor> means = means_of(sums, shapes, result.samples, false);
    GradModeGuard no_graph(false);
    result.loss = checked_loss_value(loss.outer(means));
    result.means = values_of(means);
  }
  return result;
}

StepResult train_step(Adam& optimizer, const BatchLoss& loss, const StepOptions& options) {
  const std::vector<Tensor>& params = optimizer.params();
  BatchGradient gradient = batch_gradient(params, loss, options.micro_batches);
  std::vector<Tensor>& total = gradient.grads;
  StepResult result;
  result.loss = gradient.loss;
  result.means = std::move(gradient.means);
  result.samples = gradient.samples;

  // every gradient finite (a non-finite value makes its sum of squares non-finite: look for
  // it only then), its norm, clipping; then the rate and the update
  double squares = 0;
  for (std::size_t p = 0; p < params.size(); ++p) {
    const float* g = total[p].data();
    const Eigen::Index n = total[p].numel();
    const double part = Eigen::Map<const Eigen::VectorXf>(g, n).cast<double>().squaredNorm();
    if (!std::isfinite(part)) {
      for (Eigen::Index j = 0; j < n; ++j) {
        if (!std::isfinite(g[j])) {
          refuse("the gradient of '" + optimizer.names()[p] + "' is " +
                 (std::isnan(g[j]) ? std::string("nan") : std::to_string(g[j])) + " at element " +
                 std::to_string(j) + " of " + total[p].shape().str());
        }
      }
    }
    squares += part;
  }
  result.grad_norm = std::sqrt(squares);
  if (options.clip_norm > 0)
    clip_grad_norm(total, options.clip_norm);
  if (options.schedule)
    optimizer.set_lr(options.schedule->rate(optimizer.steps()));
  result.lr = optimizer.lr();
  optimizer.step(total);
  return result;
}

}  // namespace ropes::nn
