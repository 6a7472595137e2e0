#include "ropes_nn/tensor.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>
#include <utility>
#include <vector>

#include "ropes_nn/adam.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {
namespace {

std::string error_of(const std::function<void()>& call) {
  try {
    call();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

TEST(Tensor, HoldsValuesInRowMajorOrderAndSharesStorageWhenReshaped) {
  const Tensor t(Shape{2, 3}, {1, 2, 3, 4, 5, 6});
  EXPECT_EQ(t.shape(), (Shape{2, 3}));
  EXPECT_EQ(t.numel(), 6);
  EXPECT_EQ(t.shape().str(), "[2, 3]");
  Tensor r = t.reshape(Shape{3, 2});
  r.mutable_data()[0] = 10;
  EXPECT_EQ(t.data()[0], 10);  // a view, not a copy
  EXPECT_EQ(Tensor::scalar(2.5f).item(), 2.5f);
  EXPECT_EQ(Shape().numel(), 1);
}

TEST(Tensor, RejectsBadShapesAndValuesWithBothSides) {
  EXPECT_NE(error_of([] {
              Tensor(Shape{2, 2}, {1, 2, 3});
            }).find("3 values for shape [2, 2]"),
            std::string::npos);
  EXPECT_NE(error_of([] { Shape{1, 2, 3, 4, 5}; }).find("rank 5"), std::string::npos);
  EXPECT_NE(error_of([] { Shape{2, -1}; }).find("dimension 1 is -1"), std::string::npos);
  EXPECT_NE(error_of([] {
              Tensor::zeros(Shape{2, 3}).item();
            }).find("has 6 elements"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              add(Tensor::zeros(Shape{2, 3}), Tensor::zeros(Shape{4}));
            }).find("add: shapes [2, 3] and [4] do not broadcast"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              matmul(Tensor::zeros(Shape{2, 3}), Tensor::zeros(Shape{2, 3}));
            }).find("matmul: shapes [2, 3] and [2, 3]"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              reshape(Tensor::zeros(Shape{2, 3}), Shape{4});
            }).find("cannot view shape [2, 3] (6 elements) as [4] (4)"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              sum(Tensor::zeros(Shape{2, 3}), {2});
            }).find("axis 2 is out of range"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              mean(Tensor::zeros(Shape{2, 3}), {1, -1});
            }).find("given twice"),
            std::string::npos);
  EXPECT_NE(error_of([] {
              slice(Tensor::zeros(Shape{2, 3}), 1, 2, 5);
            }).find("[2, 5) is not inside axis 1"),
            std::string::npos);
}

// forward values worked by hand
TEST(Ops, ForwardValuesMatchHandComputation) {
  const Tensor a(Shape{2, 3}, {1, 2, 3, 4, 5, 6});
  const Tensor row(Shape{3}, {10, 20, 30});
  const Tensor col(Shape{2, 1}, {100, 200});
  EXPECT_EQ(add(a, row).to_vector(), (std::vector<float>{11, 22, 33, 14, 25, 36}));
  EXPECT_EQ(mul(a, col).to_vector(), (std::vector<float>{100, 200, 300, 800, 1000, 1200}));
  EXPECT_EQ(sum(a, {0}).to_vector(), (std::vector<float>{5, 7, 9}));
  EXPECT_EQ(sum(a, {1}, true).shape(), (Shape{2, 1}));
  EXPECT_EQ(sum(a, {1}, true).to_vector(), (std::vector<float>{6, 15}));
  EXPECT_EQ(mean(a).item(), 3.5f);
  EXPECT_EQ(sum_to(a, Shape{3}).to_vector(), (std::vector<float>{5, 7, 9}));
  EXPECT_EQ(transpose(a).to_vector(), (std::vector<float>{1, 4, 2, 5, 3, 6}));
  EXPECT_EQ(matmul(a, transpose(a)).to_vector(), (std::vector<float>{14, 32, 32, 77}));
  EXPECT_EQ(concat({a, col}, 1).to_vector(), (std::vector<float>{1, 2, 3, 100, 4, 5, 6, 200}));
  EXPECT_EQ(slice(a, 1, 1, 3).to_vector(), (std::vector<float>{2, 3, 5, 6}));
  EXPECT_EQ(relu(Tensor(Shape{3}, {-1, 0, 2})).to_vector(), (std::vector<float>{0, 0, 2}));
  EXPECT_FLOAT_EQ(sigmoid(Tensor::scalar(-100.0f)).item(), 3.7200760e-44f);  // no overflow
  // BCE of logit 0 is log 2 for any target; of a large logit with target 1 about exp(-z)
  EXPECT_FLOAT_EQ(bce_with_logits(Tensor::zeros(Shape{2}), Tensor(Shape{2}, {0, 1})).item(),
                  std::log(2.0f));
  EXPECT_NEAR(bce_with_logits(Tensor::scalar(30.0f), Tensor::scalar(1.0f)).item(), 9.4e-14, 1e-15);
  // at a logit of exactly 0 the gradient is (sigmoid(0) - y) / N, as PyTorch's
  const Tensor z = Tensor::zeros(Shape{2}, true);
  EXPECT_EQ(grad({bce_with_logits(z, Tensor(Shape{2}, {0.0f, 1.0f}))}, {z})[0].to_vector(),
            (std::vector<float>{0.25f, -0.25f}));
}

TEST(Ops, TransposeMovesEveryElementOfEveryShape) {
  // the tiled copy (8 x 8 tiles in bands of 16 columns) and its edges: shapes below, at and
  // past the tile and the band, and a power-of-two square; each element checked by index
  const std::vector<std::pair<std::int64_t, std::int64_t>> shapes = {
      {1, 1},  {1, 9},   {9, 1},   {7, 7},  {8, 8},   {8, 16},   {16, 8},
      {9, 17}, {13, 37}, {24, 40}, {33, 8}, {64, 12}, {256, 256}};
  for (const auto& [m, n] : shapes) {
    std::vector<float> values(static_cast<std::size_t>(m * n));
    for (std::size_t i = 0; i < values.size(); ++i)
      values[i] = static_cast<float>(i) + 0.5f;
    const Tensor t = transpose(Tensor(Shape{m, n}, values));
    ASSERT_EQ(t.shape(), (Shape{n, m}));
    for (std::int64_t i = 0; i < m; ++i)
      for (std::int64_t j = 0; j < n; ++j)
        ASSERT_EQ(t.data()[j * m + i], values[static_cast<std::size_t>(i * n + j)])
            << m << " x " << n << " at (" << i << ", " << j << ")";
  }
}

TEST(Ops, SumsRunOverEachOutputsElementsInOrderInDouble) {
  // every set of axes of a [5, 6, 7, 9] tensor (and one large enough for the threads): each
  // output the double sum of its elements in row-major order from 0, rounded once to float,
  // bit for bit (what the plain loop over x gave; the sums are now interleaved and threaded)
  for (const Shape& shape : {Shape{5, 6, 7, 9}, Shape{8, 16, 33, 35}}) {
    std::vector<float> values(static_cast<std::size_t>(shape.numel()));
    for (std::size_t i = 0; i < values.size(); ++i)
      values[i] = std::sin(static_cast<float>(i) * 0.37f) * (1.0f + static_cast<float>(i % 11));
    const Tensor x(shape, values);
    for (int mask = 1; mask < 16; ++mask) {
      std::vector<int> axes;
      for (int a = 0; a < 4; ++a)
        if (mask & (1 << a))
          axes.push_back(a);
      const Tensor s = sum(x, axes, true);
      std::vector<double> expected(static_cast<std::size_t>(s.numel()), 0.0);
      std::int64_t k = 0;
      for (std::int64_t i0 = 0; i0 < shape[0]; ++i0)
        for (std::int64_t i1 = 0; i1 < shape[1]; ++i1)
          for (std::int64_t i2 = 0; i2 < shape[2]; ++i2)
            for (std::int64_t i3 = 0; i3 < shape[3]; ++i3) {
              const std::int64_t idx[4] = {i0, i1, i2, i3};
              std::int64_t o = 0;
              for (int a = 0; a < 4; ++a)
                o = o * s.shape()[a] + ((mask & (1 << a)) ? 0 : idx[a]);
              expected[static_cast<std::size_t>(o)] += values[static_cast<std::size_t>(k++)];
            }
      for (std::size_t o = 0; o < expected.size(); ++o)
        ASSERT_EQ(s.data()[o], static_cast<float>(expected[o]))
            << shape.str() << " axes mask " << mask << " output " << o;
    }
  }
}

// conv shapes and a value worked by hand
TEST(Ops, ConvolutionShapesFollowFlaxPaddingAndPytorchTransposeLayout) {
  const Tensor x = Tensor::ones(Shape{1, 1, 5, 5});
  EXPECT_EQ(conv2d(x, Tensor::ones(Shape{2, 1, 3, 3})).shape(), (Shape{1, 2, 5, 5}));
  EXPECT_EQ(conv2d(x, Tensor::ones(Shape{2, 1, 4, 4}), 2).shape(), (Shape{1, 2, 3, 3}));
  EXPECT_EQ(conv2d(x, Tensor::ones(Shape{2, 1, 3, 3}), 1, Padding2d::valid()).shape(),
            (Shape{1, 2, 3, 3}));
  EXPECT_EQ(
      conv_transpose2d(Tensor::ones(Shape{1, 3, 8, 8}), Tensor::ones(Shape{3, 2, 4, 4}), 2).shape(),
      (Shape{1, 2, 16, 16}));
  // 3x3 ones kernel, SAME: a corner sees 4 pixels, an edge 6, the centre 9
  const Tensor y = conv2d(x, Tensor::ones(Shape{1, 1, 3, 3}));
  EXPECT_EQ(y.data()[0], 4.0f);
  EXPECT_EQ(y.data()[1], 6.0f);
  EXPECT_EQ(y.data()[12], 9.0f);
  // stride 2, kernel 4, input 5: SAME pads 1 before and 2 after: first output sees 3x3 ones
  EXPECT_EQ(conv2d(x, Tensor::ones(Shape{1, 1, 4, 4}), 2).data()[0], 9.0f);
  EXPECT_NE(error_of([&] {
              conv2d(x, Tensor::ones(Shape{1, 2, 3, 3}));
            }).find("expected [N, C, H, W] and [O, C, KH, KW] with the same C"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              conv2d(x, Tensor::ones(Shape{1, 1, 6, 6}), 1, Padding2d::valid());
            }).find("leaves no output"),
            std::string::npos);
  EXPECT_NE(error_of([&] {
              group_norm(Tensor::ones(Shape{1, 6, 2, 2}), 4, Tensor::ones(Shape{6}),
                         Tensor::zeros(Shape{6}));
            }).find("4 groups for 6 channels"),
            std::string::npos);
}

TEST(Autograd, BackwardAccumulatesIntoLeavesAndGradReturnsWithoutTouchingThem) {
  Tensor x = Tensor(Shape{2}, {1.0f, -2.0f}, true);
  Tensor w = Tensor(Shape{2}, {3.0f, 4.0f}, true);
  const Tensor loss = sum(mul(square(x), w));  // d/dx = 2 x w, d/dw = x^2
  loss.backward();
  EXPECT_EQ(x.grad().to_vector(), (std::vector<float>{6, -16}));
  EXPECT_EQ(w.grad().to_vector(), (std::vector<float>{1, 4}));
  loss.backward();  // accumulates
  EXPECT_EQ(w.grad().to_vector(), (std::vector<float>{2, 8}));
  w.zero_grad();
  EXPECT_FALSE(w.grad().defined());
  const std::vector<Tensor> g = grad({loss}, {x});
  EXPECT_EQ(g[0].to_vector(), (std::vector<float>{6, -16}));
  EXPECT_FALSE(g[0].requires_grad());  // no create_graph: a plain tensor
}

TEST(Autograd, CreateGraphGivesDifferentiableGradients) {
  // f = x^3: f' = 3 x^2, f'' = 6 x, f''' = 6
  const Tensor x = Tensor::scalar(2.0f, true);
  const Tensor f = mul(square(x), x);
  const Tensor d1 = grad({f}, {x}, {}, true)[0];
  EXPECT_EQ(d1.item(), 12.0f);
  ASSERT_TRUE(d1.requires_grad());
  const Tensor d2 = grad({d1}, {x}, {}, true)[0];
  EXPECT_EQ(d2.item(), 12.0f);
  const Tensor d3 = grad({d2}, {x})[0];
  EXPECT_EQ(d3.item(), 6.0f);
}

TEST(Autograd, SigmoidsOnePassGradientHasTheBitsOfItsGraph) {
  // without create_graph sigmoid's backward runs one fused pass; with it, the same formula as
  // recorded operations (neg, add_scalar, mul): the two gradients must be equal bit for bit
  std::vector<float> values;
  for (int i = -40; i <= 40; ++i)
    values.push_back(0.37f * static_cast<float>(i) + 0.01f);
  const Tensor x = Tensor(Shape{static_cast<std::int64_t>(values.size())}, values, true);
  std::vector<float> weights(values.size());
  for (std::size_t i = 0; i < weights.size(); ++i)
    weights[i] = 1.0f + 0.013f * static_cast<float>(i);
  const Tensor w(x.shape(), weights);
  const Tensor loss = sum(mul(sigmoid(x), w));
  const Tensor fused = grad({loss}, {x})[0];
  const Tensor recorded = grad({loss}, {x}, {}, true)[0];
  ASSERT_TRUE(recorded.requires_grad());
  const std::vector<float> a = fused.to_vector(), b = recorded.to_vector();
  for (std::size_t i = 0; i < a.size(); ++i) {
    const float s = 1.0f / (1.0f + std::exp(-values[i]));
    EXPECT_NEAR(a[i], weights[i] * s * (1.0f - s), 1e-6f) << "at x = " << values[i];
    EXPECT_EQ(a[i], b[i]) << "at x = " << values[i];
  }
}

TEST(Autograd, GradForAnInputComputesNoGradientOfWeightsItDoesNotAskFor) {
  // y = relu(x W1) W2, W1 and W2 requiring grad: grad(y, x) needs one product per matmul
  // (g W^T), not the weights' (x^T g), which grad() would throw away; counted in FLOPs, and
  // the gradient is the same as the one computed beside the weights' in one call
  const Tensor x = Tensor(Shape{16, 8}, std::vector<float>(128, 0.25f), true);
  std::vector<float> w1(8 * 32), w2(32 * 4);
  for (std::size_t i = 0; i < w1.size(); ++i)
    w1[i] = static_cast<float>(i % 7) * 0.1f - 0.3f;
  for (std::size_t i = 0; i < w2.size(); ++i)
    w2[i] = static_cast<float>(i % 5) * 0.2f - 0.4f;
  const Tensor W1 = Tensor(Shape{8, 32}, w1, true), W2 = Tensor(Shape{32, 4}, w2, true);
  const Tensor loss = sum(matmul(relu(matmul(x, W1)), W2));
  reset_flop_count();
  const Tensor gx = grad({loss}, {x})[0];
  EXPECT_EQ(flop_count(), 2u * (16 * 4 * 32 + 16 * 32 * 8));  // g W2^T, then g W1^T
  reset_flop_count();
  const std::vector<Tensor> all = grad({loss}, {x, W1, W2});
  EXPECT_EQ(flop_count(), 4u * (16 * 4 * 32 + 16 * 32 * 8));  // and x^T g for each weight
  EXPECT_EQ(gx.to_vector(), all[0].to_vector());
}

TEST(Autograd, SharedSubexpressionsAndRepeatedInputsSumTheirPaths) {
  const Tensor x = Tensor::scalar(3.0f, true);
  const Tensor y = mul(x, x);          // 2x
  const Tensor z = add(y, mul(y, x));  // y + y x: dz/dx = 2x + 3x^2 = 33
  EXPECT_EQ(grad({z}, {x})[0].item(), 33.0f);
  // two outputs: d(y + z)/dx
  EXPECT_EQ(grad({y, z}, {x})[0].item(), 39.0f);
}

TEST(Autograd, AnInputComputedFromAnotherInputPassesItsGradientOn) {
  // y = x^2 is asked for too: d(y * x)/dx = y + x * 2x = 3x^2 = 12, d(y * x)/dy = x = 2
  const Tensor x = Tensor::scalar(2.0f, true);
  const Tensor y = square(x);
  const auto g = grad({mul(y, x)}, {x, y});
  EXPECT_EQ(g[0].item(), 12.0f);
  EXPECT_EQ(g[1].item(), 2.0f);
  // and the sweep stops at what is asked: x's history is not walked for y alone
  EXPECT_EQ(grad({mul(y, x)}, {y})[0].item(), 2.0f);
}

TEST(Autograd, ReportsMisuseClearly) {
  const Tensor x = Tensor(Shape{2}, {1, 2}, true);
  const Tensor unrelated = Tensor(Shape{2}, {1, 2}, true);
  const Tensor y = mul_scalar(x, 2.0f);
  EXPECT_NE(error_of([&] { grad({y}, {x}); }).find("output 0 has shape [2]; give grad_outputs"),
            std::string::npos);
  EXPECT_NE(error_of([&] { grad({sum(y)}, {unrelated}); }).find("do not depend on inputs[0]"),
            std::string::npos);
  EXPECT_EQ(grad({sum(y)}, {unrelated}, {}, false, true)[0].to_vector(),
            (std::vector<float>{0, 0}));
  EXPECT_NE(error_of([&] {
              grad({y}, {x}, {Tensor::ones(Shape{3})});
            }).find("grad_outputs[0] has shape [3] but output 0 has shape [2]"),
            std::string::npos);
  Tensor produced = y;
  EXPECT_NE(error_of([&] { produced.set_requires_grad(false); }).find("produced by mul_scalar"),
            std::string::npos);
  EXPECT_NE(error_of([] { Tensor::ones(Shape{1}).backward(); }).find("does not depend"),
            std::string::npos);
}

// a parameter skipped in a step keeps its own bias-correction count: its first update is the
// textbook first Adam step, lr * g / (|g| + eps) (hand-worked; PyTorch counts per parameter)
TEST(Adam, BiasCorrectionCountsEachParametersOwnUpdates) {
  Tensor a = Tensor::scalar(1.0f, true), b = Tensor::scalar(1.0f, true);
  Adam adam({a, b}, AdamOptions{0.1});
  adam.step({Tensor::scalar(0.5f), Tensor()});
  EXPECT_NEAR(a.item(), 0.9f, 1e-6);
  EXPECT_EQ(b.item(), 1.0f);
  adam.step({Tensor::scalar(0.5f), Tensor::scalar(0.5f)});
  EXPECT_NEAR(b.item(), 0.9f, 1e-6);
  EXPECT_EQ(adam.steps(), 2);
}

TEST(Autograd, NoGraphIsRecordedWithGradModeOff) {
  const Tensor x = Tensor::scalar(1.0f, true);
  GradModeGuard off(false);
  const Tensor y = square(x);
  EXPECT_FALSE(y.requires_grad());
  EXPECT_EQ(y.grad_fn(), nullptr);
}

}  // namespace
}  // namespace ropes::nn
