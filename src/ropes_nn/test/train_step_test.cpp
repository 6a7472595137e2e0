// train_step: the two-phase step is exact for a loss that squares a batch mean (the
// score-sparsity loss), whatever the micro-batch split and on 1 or 2 threads; bad losses
// and non-finite gradients are refused before any parameter changes.
#include "ropes_nn/train_step.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <memory>
#include <stdexcept>
#include <string>
#include <vector>

#include "ropes_core/philox.hpp"
#include "ropes_nn/layers.hpp"
#include "ropes_nn/ops.hpp"
#include "ropes_nn/parallel.hpp"

namespace ropes::nn {
namespace {

#define EXPECT_CONTAINS(text, part) \
  EXPECT_NE(std::string(text).find(part), std::string::npos) << "in: " << (text)

Tensor normal_tensor(const Shape& shape, std::uint64_t seed) {
  core::PhiloxStream rng(seed, 0);
  std::vector<float> v(static_cast<std::size_t>(shape.numel()));
  for (float& x : v)
    x = static_cast<float>(rng.normal());
  return Tensor(shape, v);
}

// a small AE2: codes y [N, 2, 4, 4] -> z [N, 3] -> [N, 2, 4, 4], through the operations of
// the paper's AE2 (dense, transposed convolution, group norm, convolution)
class TinyAe2 : public Module {
 public:
  TinyAe2() {
    encoder_ = register_module("encoder", std::make_shared<Dense>(32, 3));
    from_latent_ = register_module("from_latent", std::make_shared<Dense>(3, 16));
    up_ = register_module("up", std::make_shared<ConvTranspose2d>(4, 4, 4, 2));
    norm_ = register_module("norm", std::make_shared<GroupNorm>(4, 2));
    out_ = register_module("out", std::make_shared<Conv2d>(4, 2, 3));
  }
  Tensor encode(const Tensor& y) { return (*encoder_)(flatten(y)); }
  Tensor decode(const Tensor& z) {
    const Tensor h = reshape(relu((*from_latent_)(z)), Shape{z.shape()[0], 4, 2, 2});
    return (*out_)(relu((*norm_)((*up_)(h))));
  }

 protected:
  Tensor forward(const Tensor& y) override { return decode(encode(y)); }

 private:
  std::shared_ptr<Dense> encoder_, from_latent_;
  std::shared_ptr<ConvTranspose2d> up_;
  std::shared_ptr<GroupNorm> norm_;
  std::shared_ptr<Conv2d> out_;
};

struct SparsityProblem {
  TinyAe2 net;
  Tensor codes = normal_tensor(Shape{64, 2, 4, 4}, 2);
  Tensor scores = normal_tensor(Shape{64, 2, 4, 4}, 3);
  Tensor target = Tensor(Shape{3}, {0.0f, 1.0f, 0.0f});  // e_1
  SparsityProblem() { net.initialize(1); }

  // |J_g(z)^T v| per sample, for rows [begin, end)
  Tensor abs_jtv(std::int64_t begin, std::int64_t end, bool create_graph) {
    const Tensor z = net.encode(slice(codes, 0, begin, end));
    const Tensor recon = net.decode(z);
    return abs(grad({recon}, {z}, {slice(scores, 0, begin, end)}, create_graph)[0]);
  }

  // the sparsity loss || E|J_g^T v| - e_1 ||^2 as an outer function of one batch mean
  BatchLoss loss(std::size_t parts) {
    BatchLoss l;
    l.statistics = [this, parts](std::size_t i, bool create_graph) {
      const std::int64_t size = 64 / static_cast<std::int64_t>(parts);
      const std::int64_t begin = static_cast<std::int64_t>(i) * size;
      return std::vector<Tensor>{abs_jtv(begin, begin + size, create_graph)};
    };
    l.outer = [this](const std::vector<Tensor>& m) { return sum(square(sub(m[0], target))); };
    return l;
  }
};

// the largest |a - b| over all gradients, and the largest |a|
void compare(const std::vector<Tensor>& a, const std::vector<Tensor>& b, double* diff,
             double* scale) {
  *diff = 0;
  *scale = 0;
  for (std::size_t p = 0; p < a.size(); ++p) {
    for (std::int64_t j = 0; j < a[p].numel(); ++j) {
      *diff = std::max(*diff, static_cast<double>(std::abs(a[p].data()[j] - b[p].data()[j])));
      *scale = std::max(*scale, static_cast<double>(std::abs(a[p].data()[j])));
    }
  }
}

// float rounding: the micro-batch splits add the same terms in another order
constexpr double kRelativeTolerance = 1e-5;

TEST(TrainStep, SparsityGradientIsTheSameForAnyMicroBatchSplitOnOneAndTwoThreads) {
  const int saved = num_threads();
  for (int threads : {1, 2}) {
    set_num_threads(threads);
    SparsityProblem problem;
    const std::vector<Tensor> params = problem.net.parameters();
    const BatchGradient whole = batch_gradient(params, problem.loss(1), 1);

    // the reference itself: grad of the loss of the whole batch, written out here
    const Tensor direct = sum(square(sub(mean(problem.abs_jtv(0, 64, true), {0}), problem.target)));
    EXPECT_FLOAT_EQ(static_cast<float>(whole.loss), direct.item());
    double diff = 0, scale = 0;
    compare(grad({direct}, params, {}, false, true), whole.grads, &diff, &scale);
    EXPECT_EQ(diff, 0.0) << "one micro-batch is the plain gradient";
    ASSERT_GT(scale, 1e-3);

    for (std::size_t parts : {4u, 16u}) {
      const BatchGradient split = batch_gradient(params, problem.loss(parts), parts);
      EXPECT_EQ(split.samples, 64);
      EXPECT_NEAR(split.loss, whole.loss, 1e-6 * whole.loss);
      ASSERT_EQ(split.means.size(), 1u);
      for (std::size_t j = 0; j < 3; ++j)
        EXPECT_NEAR(split.means[0][j], whole.means[0][j], 1e-6) << j;
      compare(split.grads, whole.grads, &diff, &scale);
      EXPECT_LE(diff, kRelativeTolerance * scale)
          << parts << " micro-batches, " << threads << " thread(s): max difference " << diff
          << " of gradients up to " << scale;
      std::printf(
          "%d thread(s), %zu micro-batches: max |grad difference| %.3g (largest grad %.3g)\n",
          threads, parts, diff, scale);
    }

    // what summing per-micro-batch losses would give instead: another objective, far off
    std::vector<Tensor> naive(params.size());
    for (std::int64_t i = 0; i < 4; ++i) {
      const Tensor part =
          sum(square(sub(mean(problem.abs_jtv(16 * i, 16 * i + 16, true), {0}), problem.target)));
      const std::vector<Tensor> g = grad({mul_scalar(part, 0.25f)}, params, {}, false, true);
      for (std::size_t p = 0; p < params.size(); ++p)
        naive[p] = naive[p].defined() ? add(naive[p], g[p]) : g[p];
    }
    compare(naive, whole.grads, &diff, &scale);
    EXPECT_GT(diff, 100 * kRelativeTolerance * scale) << "the test would not see the difference";
  }
  set_num_threads(saved);
}

TEST(TrainStep, MeanLossGradientIsTheSameForAnyMicroBatchSplitOnOneAndTwoThreads) {
  const int saved = num_threads();
  for (int threads : {1, 2}) {
    set_num_threads(threads);
    SparsityProblem problem;
    const std::vector<Tensor> params = problem.net.parameters();
    // per-sample reconstruction error: a mean loss, declared affine or not
    auto loss = [&](std::size_t parts, bool affine) {
      BatchLoss l = mean_loss([&problem, parts](std::size_t i) {
        const std::int64_t size = 64 / static_cast<std::int64_t>(parts);
        const Tensor y = slice(problem.codes, 0, static_cast<std::int64_t>(i) * size,
                               static_cast<std::int64_t>(i + 1) * size);
        return mean(square(sub(problem.net(y), y)), {1, 2, 3});
      });
      l.outer_is_affine = affine;
      return l;
    };
    const BatchGradient whole = batch_gradient(params, loss(1, true), 1);
    const Tensor direct = mse_loss(problem.net(problem.codes), problem.codes);
    EXPECT_NEAR(whole.loss, direct.item(), 1e-6 * direct.item());
    for (std::size_t parts : {4u, 16u}) {
      for (bool affine : {true, false}) {
        const BatchGradient split = batch_gradient(params, loss(parts, affine), parts);
        double diff = 0, scale = 0;
        compare(split.grads, whole.grads, &diff, &scale);
        EXPECT_LE(diff, kRelativeTolerance * scale)
            << parts << " micro-batches, affine " << affine << ", " << threads << " thread(s)";
        EXPECT_NEAR(split.loss, whole.loss, 1e-6 * whole.loss);
      }
    }
  }
  set_num_threads(saved);
}

TEST(TrainStep, AppliesTheScheduleRateAndReportsTheStep) {
  SparsityProblem problem;
  Adam adam(problem.net.named_parameters(), AdamOptions{1.0});
  const LrSchedule schedule = LrSchedule::linear_warmup(1e-3, 4);
  StepOptions options;
  options.micro_batches = 4;
  options.schedule = &schedule;
  for (int step = 0; step < 5; ++step) {
    const StepResult r = train_step(adam, problem.loss(4), options);
    EXPECT_DOUBLE_EQ(r.lr, schedule.rate(step));
    EXPECT_EQ(r.samples, 64);
    EXPECT_GT(r.grad_norm, 0);
  }
  EXPECT_EQ(adam.steps(), 5);
  EXPECT_DOUBLE_EQ(adam.lr(), 1e-3);
}

// With eps far above |m| / sqrt(v), Adam's update is lr g / eps: linear in the gradient, so
// clipping to a tenth of the norm shows as a tenth of the step
TEST(TrainStep, ClipsToTheGivenNormAndReportsTheNormBefore) {
  SparsityProblem clipped, plain;
  const BatchGradient g = batch_gradient(clipped.net.parameters(), clipped.loss(4), 4);
  double norm = 0;
  for (const Tensor& t : g.grads)
    for (std::int64_t j = 0; j < t.numel(); ++j)
      norm += static_cast<double>(t.data()[j]) * t.data()[j];
  norm = std::sqrt(norm);
  const AdamOptions linear{1e3, 0.0, 0.0, 1e6};  // a step of 1e-3 g: well above float rounding
  Adam adam_clipped(clipped.net.named_parameters(), linear);
  Adam adam_plain(plain.net.named_parameters(), linear);
  const std::vector<float> before = clipped.net.parameters()[0].to_vector();
  StepOptions options;
  options.micro_batches = 4;
  options.clip_norm = norm / 10;
  EXPECT_NEAR(train_step(adam_clipped, clipped.loss(4), options).grad_norm, norm, 1e-6 * norm);
  options.clip_norm = 0;
  EXPECT_NEAR(train_step(adam_plain, plain.loss(4), options).grad_norm, norm, 1e-6 * norm);
  const std::vector<float> after_clipped = clipped.net.parameters()[0].to_vector();
  const std::vector<float> after_plain = plain.net.parameters()[0].to_vector();
  double moved_clipped = 0, moved_plain = 0;
  for (std::size_t j = 0; j < before.size(); ++j) {
    moved_clipped += std::abs(after_clipped[j] - before[j]);
    moved_plain += std::abs(after_plain[j] - before[j]);
  }
  ASSERT_GT(moved_plain, 0);
  EXPECT_NEAR(moved_clipped / moved_plain, 0.1, 1e-3);
}

TEST(TrainStep, RefusesANonFiniteGradientNamingTheParameterAndChangesNothing) {
  // sqrt(w x) at w = x = 0: the loss is 0, its gradient 0 * inf = NaN
  class Root : public Module {
   public:
    Root() { w_ = register_parameter("weight", Shape{1}, "zeros"); }

   protected:
    Tensor forward(const Tensor& x) override { return sqrt(mul(x, w_)); }

   private:
    Tensor w_;
  };
  auto root = std::make_shared<Root>();
  Sequential net;
  net.add(root, "root");
  net.initialize(1);
  Adam adam(net.named_parameters(), AdamOptions{0.1});
  const BatchLoss loss = mean_loss([&](std::size_t) { return net(Tensor::zeros(Shape{4})); });
  for (std::size_t parts : {1u, 2u}) {
    StepOptions options;
    options.micro_batches = parts;
    try {
      train_step(adam, loss, options);
      ADD_FAILURE() << "a NaN gradient was applied";
    } catch (const std::invalid_argument& e) {
      EXPECT_CONTAINS(e.what(), "the gradient of 'root.weight' is nan at element 0");
      EXPECT_CONTAINS(e.what(), "no parameter was changed");
    }
  }
  EXPECT_EQ(net.parameters()[0].item(), 0.0f);
  EXPECT_EQ(adam.steps(), 0);
}

TEST(Adam, RefusesUnnamedOrRepeatedParametersAndBadRates) {
  const Tensor a = Tensor::zeros(Shape{2}, true), b = Tensor::zeros(Shape{3}, true);
  auto error = [](const std::function<void()>& f) {
    try {
      f();
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  EXPECT_CONTAINS(error([&] {
                    Adam({{"w", a}, {"w", b}});
                  }),
                  "Adam: parameter 1 is named 'w'; expected a distinct, non-empty name");
  EXPECT_CONTAINS(error([&] { Adam({{"", a}}); }), "parameter 0 is named ''");
  EXPECT_CONTAINS(error([&] {
                    Adam({{"w", Tensor::zeros(Shape{2})}});
                  }),
                  "Adam: parameter 'w' is not a leaf tensor that requires grad");
  Adam adam({{"w", a}});
  EXPECT_CONTAINS(error([&] { adam.set_lr(-1); }), "Adam::set_lr: -1.000000; expected a finite");
  EXPECT_CONTAINS(error([&] { adam.set_lr(std::nan("")); }), "expected a finite rate >= 0");
  adam.set_lr(0);  // the end of a schedule
  EXPECT_EQ(adam.lr(), 0.0);
  EXPECT_CONTAINS(error([&] { adam.set_param_steps(0, -2); }), "'w' gets -2 steps");
  EXPECT_CONTAINS(error([&] {
                    adam.set_options(AdamOptions{1e-3, 1.0});
                  }),
                  "Adam::set_options: lr=0.001000 beta1=1.000000");
  EXPECT_CONTAINS(error([&] { adam.step({Tensor::zeros(Shape{3})}); }),
                  "gradient of 'w' has shape [3]; its parameter has [2]");
  EXPECT_EQ(adam.steps(), 0);
}

TEST(TrainStep, RefusesNonFiniteLossesAndMalformedStatistics) {
  SparsityProblem problem;
  Adam adam(problem.net.named_parameters(), AdamOptions{0.1});
  const std::vector<float> before = problem.net.parameters()[0].to_vector();
  auto error_of = [&](const BatchLoss& loss, std::size_t parts) {
    StepOptions options;
    options.micro_batches = parts;
    try {
      train_step(adam, loss, options);
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  BatchLoss infinite = problem.loss(4);
  infinite.outer = [](const std::vector<Tensor>& m) { return log(mul_scalar(sum(m[0]), 0.0f)); };
  EXPECT_CONTAINS(error_of(infinite, 4), "the loss is -inf");
  EXPECT_CONTAINS(error_of(infinite, 1), "the loss is -inf");

  BatchLoss scalar = problem.loss(4);
  scalar.statistics = [](std::size_t, bool) { return std::vector<Tensor>{Tensor::scalar(1)}; };
  EXPECT_CONTAINS(error_of(scalar, 2),
                  "micro-batch 0, statistic 0 has shape []; expected "
                  "[samples, ...]");
  BatchLoss ragged = problem.loss(4);
  ragged.statistics = [](std::size_t i, bool) {
    return std::vector<Tensor>{Tensor::ones(Shape{4, i == 0 ? 3 : 2})};
  };
  EXPECT_CONTAINS(error_of(ragged, 2),
                  "micro-batch 1, statistic 0 has shape [4, 2]; expected "
                  "[samples] + [3], as in micro-batch 0");
  BatchLoss uneven = problem.loss(4);
  uneven.statistics = [](std::size_t, bool) {
    return std::vector<Tensor>{Tensor::ones(Shape{4}), Tensor::ones(Shape{5})};
  };
  uneven.outer = [](const std::vector<Tensor>& m) { return add(m[0], m[1]); };
  EXPECT_CONTAINS(error_of(uneven, 2), "statistic 1 has 5 samples (shape [5]); statistic 0 has 4");
  EXPECT_CONTAINS(error_of(problem.loss(4), 0), "0 micro-batches");
  EXPECT_CONTAINS(error_of(BatchLoss{}, 1), "lacks its statistics or outer function");
  EXPECT_EQ(problem.net.parameters()[0].to_vector(), before);
  EXPECT_EQ(adam.steps(), 0);
}

}  // namespace
}  // namespace ropes::nn
