// A warm forward pass without grad mode allocates nothing from the system: the layers of the
// ROPES networks (patchify stem, 3x3 convolutions with stride 1 and 2, ResBlockGN, GroupNorm,
// ReLU, Dense, SiLU as x * sigmoid(x), reshape) take their results' storage and their tensor
// handles from the buffer pool, build no autodiff node and no list of inputs, and run their
// matrix products on per-thread workspaces. Its own executable: allocation_counter.hpp
// interposes malloc for the whole process.
#include <ropes_core/philox.hpp>
#include <ropes_nn/allocation_counter.hpp>
#include <ropes_nn/layers.hpp>
#include <ropes_nn/ops.hpp>
#include <ropes_nn/parallel.hpp>

#include <gtest/gtest.h>

#include <memory>
#include <vector>

namespace ropes::nn {
namespace {

// a sanitizer build owns malloc: nothing is counted there (allocation_counter.hpp)
#define ROPES_SKIP_WITHOUT_COUNTER()  \
  if (!allocation_counter::available) \
  GTEST_SKIP() << "built with AddressSanitizer: allocation_counter.hpp counts nothing"

// an AE1-style encoder and an MLP head: [1, 1, 64, 64] -> [1, 4]
class Net {
 public:
  Net() {
    encoder_.add(std::make_shared<Conv2d>(1, 16, 4, 4, Padding2d::valid()));
    encoder_.add(std::make_shared<Conv2d>(16, 32, 3));
    encoder_.add(std::make_shared<ResBlockGN>(32));
    encoder_.add(std::make_shared<Conv2d>(32, 32, 3, 2));
    encoder_.add(std::make_shared<ReLU>());
    encoder_.add(std::make_shared<GroupNorm>(32, 8));
    encoder_.initialize(5, "encoder");
    hidden_.initialize(6, "hidden");
    out_.initialize(7, "out");
  }
  Tensor operator()(const Tensor& x) {
    const Tensor y = encoder_(x);
    const Tensor h = hidden_(reshape(y, Shape{y.shape()[0], 32 * 8 * 8}));
    return out_(mul(h, sigmoid(h)));
  }

 private:
  Sequential encoder_;
  Dense hidden_{32 * 8 * 8, 256}, out_{256, 4};
};

Tensor image() {
  core::PhiloxStream rng(3, 0);
  Buffer pixels(64 * 64);
  for (float& v : pixels)
    v = rng.uniform_float();
  return Tensor(Shape{1, 1, 64, 64}, std::move(pixels));
}

TEST(Allocation, WarmForwardWithoutGradModeAllocatesNothing) {
  ROPES_SKIP_WITHOUT_COUNTER();
  const int saved = num_threads();
  Net net;
  std::vector<float> reference;
  // 3 and 4 threads oversubscribe 2 cores, which is fine: OpenMP teams of several sizes are
  // what made warm calls allocate
  for (int threads : {1, 2, 3, 4}) {
    set_num_threads(threads);
    GradModeGuard no_grad(false);
    std::vector<float> first;
    for (int i = 0; i < 3; ++i)  // warm-up: the pool, the workspaces and the team fill
      first = net(image()).to_vector();
    std::vector<float> outputs;
    outputs.reserve(10 * first.size());
    allocation_counter::start();
    for (int i = 0; i < 10; ++i) {
      const Tensor z = net(image());
      outputs.insert(outputs.end(), z.data(), z.data() + z.numel());
    }
    const std::uint64_t allocations = allocation_counter::stop();
    EXPECT_EQ(allocations, 0u) << threads << " thread(s)";
    for (std::size_t i = 0; i < outputs.size(); ++i)
      ASSERT_EQ(outputs[i], first[i % first.size()]) << threads << " thread(s), output " << i;
    if (reference.empty())
      reference = first;
    EXPECT_EQ(first, reference) << threads << " thread(s) against 1";
  }
  set_num_threads(saved);
}

// the counter is not blind: the same pass recording a graph allocates its nodes
TEST(Allocation, TheCounterSeesTheGraphsNodes) {
  ROPES_SKIP_WITHOUT_COUNTER();
  Net net;
  const Tensor x = image();
  for (int i = 0; i < 3; ++i)
    net(x);
  allocation_counter::start();
  const Tensor z = net(x);
  const std::uint64_t allocations = allocation_counter::stop();
  EXPECT_TRUE(z.requires_grad());
  EXPECT_GT(allocations, 10u);
}

}  // namespace
}  // namespace ropes::nn
