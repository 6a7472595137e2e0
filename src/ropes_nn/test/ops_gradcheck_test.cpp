// Every operation against central finite differences (gradcheck.hpp), and the operations on
// the AE2 path (conv, group norm, dense, relu, abs, mean, square and what they are built
// from) also at second order.
#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

#include "ropes_core/philox.hpp"
#include "ropes_nn/gradcheck.hpp"
#include "ropes_nn/layers.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {
namespace {

// values in +-[0.2, 1.2]: away from the kinks of relu and abs at 0
Tensor random_tensor(const Shape& shape, std::uint64_t stream) {
  core::PhiloxStream rng(77, stream);
  std::vector<float> v(static_cast<std::size_t>(shape.numel()));
  for (float& x : v) {
    const float magnitude = 0.2f + rng.uniform_float();
    x = rng.uniform_float() < 0.5f ? -magnitude : magnitude;
  }
  return Tensor(shape, v);
}
std::vector<float> values(const Tensor& t) {
  return std::vector<float>(t.data(), t.data() + t.numel());
}
Tensor positive_tensor(const Shape& shape, std::uint64_t stream) {
  return abs(random_tensor(shape, stream)).detach();
}

void expect_first_order(const char* what, const TensorFunction& f, const std::vector<Tensor>& xs) {
  const GradCheckResult r = check_gradients(f, xs);
  EXPECT_TRUE(r.ok) << what << ":\n" << r.report;
}
void expect_second_order(const char* what, const TensorFunction& f, const std::vector<Tensor>& xs) {
  const GradCheckResult r = check_second_gradients(f, xs);
  EXPECT_TRUE(r.ok) << what << " (second order):\n" << r.report;
}

TEST(GradCheck, BinaryOpsWithBroadcasting) {
  const Tensor a = random_tensor(Shape{2, 3, 4}, 1);
  const Tensor b = random_tensor(Shape{3, 1}, 2);
  const Tensor p = positive_tensor(Shape{1, 4}, 3);
  using V = std::vector<Tensor>;
  expect_first_order("add", [](const V& x) { return add(x[0], x[1]); }, {a, b});
  expect_first_order("sub", [](const V& x) { return sub(x[0], x[1]); }, {a, b});
  expect_first_order("mul", [](const V& x) { return mul(x[0], x[1]); }, {a, b});
  expect_first_order("div", [](const V& x) { return div(x[0], x[1]); }, {a, p});
  expect_first_order("add_scalar", [](const V& x) { return add_scalar(x[0], 0.5f); }, {a});
  expect_first_order("mul_scalar", [](const V& x) { return mul_scalar(x[0], -1.5f); }, {a});
}

TEST(GradCheck, UnaryOps) {
  const Tensor x = random_tensor(Shape{3, 5}, 4);
  const Tensor p = positive_tensor(Shape{3, 5}, 5);
  using V = std::vector<Tensor>;
  expect_first_order("neg", [](const V& v) { return neg(v[0]); }, {x});
  expect_first_order("exp", [](const V& v) { return exp(v[0]); }, {x});
  expect_first_order("log", [](const V& v) { return log(v[0]); }, {p});
  expect_first_order("log1p", [](const V& v) { return log1p(v[0]); }, {p});
  expect_first_order("sqrt", [](const V& v) { return sqrt(v[0]); }, {p});
  expect_first_order("square", [](const V& v) { return square(v[0]); }, {x});
  expect_first_order("abs", [](const V& v) { return abs(v[0]); }, {x});
  expect_first_order("relu", [](const V& v) { return relu(v[0]); }, {x});
  expect_first_order("sigmoid", [](const V& v) { return sigmoid(v[0]); }, {x});
}

TEST(GradCheck, ShapeAndReductionOps) {
  const Tensor x = random_tensor(Shape{2, 3, 2, 2}, 6);
  const Tensor y = random_tensor(Shape{2, 1, 2, 2}, 7);
  using V = std::vector<Tensor>;
  expect_first_order("reshape", [](const V& v) { return reshape(v[0], Shape{6, 4}); }, {x});
  expect_first_order("flatten", [](const V& v) { return flatten(v[0]); }, {x});
  expect_first_order("broadcast_to",
                     [](const V& v) {
                       return broadcast_to(v[0], Shape{2, 3, 2, 2});
                     },
                     {y});
  expect_first_order("sum_to", [](const V& v) { return sum_to(v[0], Shape{3, 1, 2}); }, {x});
  expect_first_order("concat", [](const V& v) { return concat({v[0], v[1]}, 1); }, {x, y});
  expect_first_order("slice", [](const V& v) { return slice(v[0], 1, 1, 3); }, {x});
  expect_first_order("transpose",
                     [](const V& v) {
                       return transpose(reshape(v[0], Shape{4, 6}));
                     },
                     {x});
  expect_first_order("sum", [](const V& v) { return sum(v[0]); }, {x});
  expect_first_order("sum axes", [](const V& v) { return sum(v[0], {0, -1}); }, {x});
  expect_first_order("sum keepdim", [](const V& v) { return sum(v[0], {1}, true); }, {x});
  expect_first_order("mean", [](const V& v) { return mean(v[0]); }, {x});
  expect_first_order("mean axes", [](const V& v) { return mean(v[0], {2, 3}); }, {x});
}

TEST(GradCheck, MatmulAndLosses) {
  const Tensor a = random_tensor(Shape{3, 4}, 8);
  const Tensor b = random_tensor(Shape{4, 2}, 9);
  const Tensor t = random_tensor(Shape{3, 4}, 10);
  const Tensor labels = Tensor(Shape{3, 4}, {0, 1, 1, 0, 1, 0, 0, 1, 0.5f, 1, 0, 0});
  using V = std::vector<Tensor>;
  expect_first_order("matmul", [](const V& v) { return matmul(v[0], v[1]); }, {a, b});
  expect_first_order("mse_loss", [](const V& v) { return mse_loss(v[0], v[1]); }, {a, t});
  expect_first_order(
      "bce_with_logits",
      [&labels](const V& v) { return bce_with_logits(mul_scalar(v[0], 4.0f), labels); }, {a});
  // per element: the logits and the targets (a soft label's gradient is -z)
  expect_first_order(
      "bce_with_logits_elementwise",
      [](const V& v) { return bce_with_logits_elementwise(mul_scalar(v[0], 4.0f), sigmoid(v[1])); },
      {a, t});
}

TEST(Losses, ElementwiseBceAveragesToBceWithLogits) {
  const Tensor z = mul_scalar(random_tensor(Shape{5, 3}, 15), 6.0f);
  const Tensor y = Tensor(Shape{5, 3}, {0, 1, 1, 0, 1, 0, 0, 1, 0.5f, 1, 0, 0, 1, 1, 0});
  const Tensor each = bce_with_logits_elementwise(z, y);
  EXPECT_EQ(each.shape(), z.shape());
  EXPECT_NEAR(mean(each).item(), bce_with_logits(z, y).item(), 1e-6);
  EXPECT_THROW(bce_with_logits_elementwise(z, Tensor::zeros(Shape{5})), std::invalid_argument);
}

// second order: what the score-sparsity loss differentiates through
TEST(GradCheck, SecondOrderOnTheAe2PathOps) {
  const Tensor a = random_tensor(Shape{3, 4}, 11);
  const Tensor b = random_tensor(Shape{4, 2}, 12);
  const Tensor c = random_tensor(Shape{1, 2}, 13);
  using V = std::vector<Tensor>;
  // dense: x W + b, with a nonlinearity so the second derivative is not trivially zero
  expect_second_order("dense + square",
                      [](const V& v) { return square(add(matmul(v[0], v[1]), v[2])); }, {a, b, c});
  expect_second_order("relu * x", [](const V& v) { return mul(relu(v[0]), v[0]); }, {a});
  expect_second_order("abs * x", [](const V& v) { return mul(abs(v[0]), v[0]); }, {a});
  expect_second_order("mean of squares", [](const V& v) { return mean(square(v[0]), {1}); }, {a});
  expect_second_order("sigmoid", [](const V& v) { return sigmoid(v[0]); }, {a});
  expect_second_order("div and sqrt",
                      [](const V& v) { return div(v[0], sqrt(add_scalar(square(v[1]), 1.0f))); },
                      {a, random_tensor(Shape{3, 4}, 14)});
  expect_second_order("broadcast, sum_to, concat, slice",
                      [](const V& v) {
                        const Tensor wide = mul(broadcast_to(v[1], Shape{3, 2}), v[1]);
                        return slice(concat({square(v[0]), wide}, 1), 1, 2, 6);
                      },
                      {a, c});
}

TEST(GradCheck, ConvolutionsAndGroupNorm) {
  const Tensor x = random_tensor(Shape{2, 3, 5, 5}, 20);
  const Tensor w3 = random_tensor(Shape{4, 3, 3, 3}, 21);
  const Tensor w4 = random_tensor(Shape{4, 3, 4, 4}, 22);
  const Tensor wt = random_tensor(Shape{3, 2, 4, 4}, 23);
  const Tensor gamma = random_tensor(Shape{3}, 24);
  const Tensor beta = random_tensor(Shape{3}, 25);
  using V = std::vector<Tensor>;
  expect_first_order("conv2d same", [](const V& v) { return conv2d(v[0], v[1]); }, {x, w3});
  expect_first_order("conv2d stride 2 same (asymmetric pad)",
                     [](const V& v) { return conv2d(v[0], v[1], 2); }, {x, w4});
  expect_first_order("conv2d valid",
                     [](const V& v) { return conv2d(v[0], v[1], 1, Padding2d::valid()); }, {x, w3});
  expect_first_order(
      "conv2d explicit",
      [](const V& v) { return conv2d(v[0], v[1], 2, Padding2d::explicit_pads(0, 2, 1, 0)); },
      {x, w3});
  expect_first_order("conv_transpose2d k4 s2 same",
                     [](const V& v) { return conv_transpose2d(v[0], v[1], 2); }, {x, wt});
  expect_first_order("conv_transpose2d explicit",
                     [](const V& v) {
                       return conv_transpose2d(v[0], v[1], 2, Padding2d::explicit_pads(1, 0, 0, 2));
                     },
                     {x, wt});
  expect_first_order("group_norm", [](const V& v) { return group_norm(v[0], 3, v[1], v[2]); },
                     {x, gamma, beta});
  expect_first_order("group_norm_relu",
                     [](const V& v) { return group_norm_relu(v[0], 3, v[1], v[2]); },
                     {x, gamma, beta});
}

TEST(GradCheck, SecondOrderThroughConvolutionsAndGroupNorm) {
  const Tensor x = random_tensor(Shape{1, 2, 4, 4}, 30);
  const Tensor w = random_tensor(Shape{2, 2, 3, 3}, 31);
  const Tensor wt = random_tensor(Shape{2, 2, 4, 4}, 32);
  const Tensor gamma = random_tensor(Shape{2}, 33);
  const Tensor beta = random_tensor(Shape{2}, 34);
  using V = std::vector<Tensor>;
  // bilinear in (x, w): squared so that the second derivative in each alone is not zero
  expect_second_order("conv2d", [](const V& v) { return square(conv2d(v[0], v[1], 2)); }, {x, w});
  expect_second_order("conv_transpose2d",
                      [](const V& v) { return square(conv_transpose2d(v[0], v[1], 2)); }, {x, wt});
  expect_second_order("group_norm", [](const V& v) { return group_norm(v[0], 1, v[1], v[2]); },
                      {x, gamma, beta});
  expect_second_order("group_norm_relu",
                      [](const V& v) { return square(group_norm_relu(v[0], 1, v[1], v[2])); },
                      {x, gamma, beta});
  expect_second_order("group_norm, 2 groups, input computed from its own scale",
                      [](const V& v) {
                        // gamma also produces the input: group norm's differentiable backward
                        // must count the path through x once (the outer sweep does)
                        const Tensor h = mul(v[0], reshape(v[1], Shape{1, 2, 1, 1}));
                        return square(group_norm(h, 2, v[1], v[2]));
                      },
                      {x, gamma, beta});
}

// group_norm_relu is relu(group_norm(...)) fused: the witness is the unfused pair, which it must
// equal bit for bit in value and in each gradient. The shapes: several channels a group, a
// count of (sample, group) sums that is not a multiple of the interleaved chains, batches
// over several reduction blocks, one group, rank 3 and rank 2.
TEST(GroupNormRelu, IsReluOfGroupNormBitForBit) {
  struct Case {
    Shape x;
    int groups;
  };
  for (const Case& c :
       {Case{Shape{3, 6, 5, 7}, 3}, Case{Shape{10, 8, 16, 16}, 8}, Case{Shape{1, 4, 3, 3}, 1},
        Case{Shape{5, 12, 9}, 4}, Case{Shape{5, 12}, 4}}) {
    const std::int64_t channels = c.x[1];
    Tensor x = random_tensor(c.x, 40);
    Tensor gamma = random_tensor(Shape{channels}, 41);
    Tensor beta = random_tensor(Shape{channels}, 42);
    const Tensor upstream = random_tensor(c.x, 43);
    for (Tensor* t : {&x, &gamma, &beta})
      t->set_requires_grad(true);
    const Tensor fused = group_norm_relu(x, c.groups, gamma, beta);
    const Tensor pair = relu(group_norm(x, c.groups, gamma, beta));
    const std::string what = "x " + c.x.str() + ", " + std::to_string(c.groups) + " groups";
    EXPECT_EQ(values(fused), values(pair)) << what;
    const std::vector<Tensor> g_fused = grad({sum(mul(fused, upstream))}, {x, gamma, beta});
    const std::vector<Tensor> g_pair = grad({sum(mul(pair, upstream))}, {x, gamma, beta});
    for (std::size_t i = 0; i < 3; ++i)
      EXPECT_EQ(values(g_fused[i]), values(g_pair[i])) << what << ", gradient " << i;
  }
}

TEST(GradCheck, EveryModule) {
  struct Case {
    const char* what;
    std::shared_ptr<Module> module;
    Shape input;
  };
  auto seq = std::make_shared<Sequential>();
  seq->add(std::make_shared<Conv2d>(2, 4, 3, 2)).add(std::make_shared<ReLU>());
  seq->add(std::make_shared<ConvTranspose2d>(4, 2, 4, 2));
  const std::vector<Case> cases = {
      {"Conv2d", std::make_shared<Conv2d>(2, 3, 3, 2), Shape{2, 2, 5, 5}},
      {"ConvTranspose2d", std::make_shared<ConvTranspose2d>(2, 3, 4, 2), Shape{2, 2, 3, 3}},
      {"GroupNorm", std::make_shared<GroupNorm>(4, 2), Shape{2, 4, 3, 3}},
      {"Dense", std::make_shared<Dense>(5, 3), Shape{4, 5}},
      {"ReLU", std::make_shared<ReLU>(), Shape{3, 4}},
      {"ResBlockGN", std::make_shared<ResBlockGN>(4, 2), Shape{1, 4, 4, 4}},
      {"Sequential", seq, Shape{1, 2, 6, 6}},
  };
  std::uint64_t stream = 40;
  for (const Case& c : cases) {
    c.module->initialize(5);
    // perturb the zero-initialised biases and unit scales so every term is exercised
    for (Tensor p : c.module->parameters()) {
      const Tensor noise = mul_scalar(random_tensor(p.shape(), stream++), 0.3f);
      for (std::int64_t i = 0; i < p.numel(); ++i)
        p.mutable_data()[i] += noise.data()[i];
    }
    // a small step: the blocks' ReLUs after group norm have kinks near many points
    GradCheckOptions options;
    options.step = 1e-3;
    const GradCheckResult r =
        check_module_gradients(*c.module, random_tensor(c.input, stream++), options);
    EXPECT_TRUE(r.ok) << c.what << ":\n" << r.report;
  }
}

// a deliberately wrong gradient must be caught: the checker itself can fail
TEST(GradCheck, CatchesAWrongGradient) {
  class WrongSquare final : public Node {
   public:
    const char* name() const override { return "wrong_square"; }
    std::vector<Tensor> backward(const Tensor& g) override {
      return {mul(g, inputs[0])};  // should be 2 x
    }
  };
  const TensorFunction f = [](const std::vector<Tensor>& v) {
    Buffer out(v[0].data(), v[0].data() + v[0].numel());
    for (float& x : out)
      x *= x;
    return make_op_result(v[0].shape(), out, std::make_shared<WrongSquare>(), {v[0]});
  };
  const GradCheckResult r = check_gradients(f, {random_tensor(Shape{4}, 15)});
  EXPECT_FALSE(r.ok);
  EXPECT_NE(r.report.find("analytic"), std::string::npos) << r.report;
}

// a first derivative that is right but not differentiable (a constant 2x) must fail at
// second order while passing at first order
TEST(GradCheck, CatchesAGradientThatIsNotDifferentiable) {
  class DetachedSquare final : public Node {
   public:
    const char* name() const override { return "detached_square"; }
    std::vector<Tensor> backward(const Tensor& g) override {
      return {mul(g, mul_scalar(inputs[0], 2.0f).detach())};
    }
  };
  const TensorFunction f = [](const std::vector<Tensor>& v) {
    Buffer out(v[0].data(), v[0].data() + v[0].numel());
    for (float& x : out)
      x *= x;
    return make_op_result(v[0].shape(), out, std::make_shared<DetachedSquare>(), {v[0]});
  };
  const Tensor x = random_tensor(Shape{4}, 16);
  EXPECT_TRUE(check_gradients(f, {x}).ok);
  const GradCheckResult second = check_second_gradients(f, {x});
  EXPECT_FALSE(second.ok) << second.report;
}

}  // namespace
}  // namespace ropes::nn
