// The threading contract of parallel.hpp: the same bits at every thread count.
#include "ropes_nn/parallel.hpp"

#include <gtest/gtest.h>

#include <atomic>
#include <cmath>
#include <stdexcept>
#include <string>
#include <thread>
#include <vector>

#include "ropes_core/philox.hpp"
#include "ropes_nn/layers.hpp"
#include "ropes_nn/ops.hpp"

namespace ropes::nn {
namespace {

// loss and every parameter gradient of a small conv net and an MLP head on a batch of 20
// (more images than reduction blocks, in blocks of unequal size)
std::vector<float> loss_and_gradients_at_current_threads() {
  Sequential net;
  net.add(std::make_shared<Conv2d>(2, 8, 3, 2));
  net.add(std::make_shared<ResBlockGN>(8, 4));
  net.add(std::make_shared<ConvTranspose2d>(8, 2, 4, 2));
  net.initialize(11);
  Sequential head;
  head.add(std::make_shared<Dense>(2 * 16 * 16, 96));
  head.add(std::make_shared<Dense>(96, 3));
  head.initialize(13);
  core::PhiloxStream rng(12, 0);
  std::vector<float> pixels(20 * 2 * 16 * 16);
  for (float& v : pixels)
    v = static_cast<float>(rng.normal());
  const Tensor x(Shape{20, 2, 16, 16}, pixels);
  const Tensor y = net(x);
  const Tensor loss = add(mse_loss(y, x), mean(head(reshape(y, Shape{20, 2 * 16 * 16}))));
  std::vector<float> out = {loss.item()};
  std::vector<Tensor> parameters = net.parameters();
  for (const Tensor& p : head.parameters())
    parameters.push_back(p);
  for (const Tensor& g : grad({loss}, parameters)) {
    const std::vector<float> v = g.to_vector();
    out.insert(out.end(), v.begin(), v.end());
  }
  return out;
}

std::vector<float> loss_and_gradients(int threads) {
  set_num_threads(threads);
  return loss_and_gradients_at_current_threads();
}

TEST(Parallel, SameThreadCountGivesBitIdenticalResults) {
  const int saved = num_threads();
  EXPECT_EQ(loss_and_gradients(2), loss_and_gradients(2));
  EXPECT_EQ(loss_and_gradients(1), loss_and_gradients(1));
  set_num_threads(saved);
}

TEST(Parallel, OtherThreadCountsGiveTheSameBits) {
  const int saved = num_threads();
  const std::vector<float> one = loss_and_gradients(1);
  EXPECT_EQ(loss_and_gradients(2), one);
  EXPECT_EQ(loss_and_gradients(3), one);
  set_num_threads(saved);
}

// conv2d's forward runs its product on a row split that keeps each output's arithmetic (see
// src/gemm.hpp): one image gives the same bits alone at any thread count and inside a batch,
// which is what makes a streamed frame's estimate equal the batch evaluation's.
TEST(Parallel, ConvolutionForwardIsBitIdenticalAcrossThreadsAndBatches) {
  struct Case {
    std::int64_t c, o, size, kernel;
    int stride;
  };
  // the small preset's stem and stages, output channels that do and do not fill whole
  // 16-row quanta, and a product big enough for three threads
  const Case cases[] = {{1, 16, 128, 4, 4}, {16, 32, 32, 3, 1}, {32, 64, 16, 3, 2},
                        {8, 80, 20, 3, 1},  {24, 47, 18, 3, 1}, {64, 96, 16, 3, 1}};
  const int saved = num_threads();
  for (const Case& k : cases) {
    core::PhiloxStream rng(static_cast<std::uint64_t>(k.o), 0);
    std::vector<float> xs(static_cast<std::size_t>(3 * k.c * k.size * k.size));
    std::vector<float> ws(static_cast<std::size_t>(k.o * k.c * k.kernel * k.kernel));
    for (float& v : xs)
      v = static_cast<float>(rng.normal());
    for (float& v : ws)
      v = static_cast<float>(rng.normal());
    const Tensor batch(Shape{3, k.c, k.size, k.size}, xs);
    const Tensor w(Shape{k.o, k.c, k.kernel, k.kernel}, ws);
    const Tensor one = slice(batch, 0, 1, 2);
    set_num_threads(1);
    const std::vector<float> alone1 = conv2d(one, w, k.stride).to_vector();
    set_num_threads(2);
    const std::vector<float> alone2 = conv2d(one, w, k.stride).to_vector();
    const Tensor batch2 = conv2d(batch, w, k.stride);
    set_num_threads(3);
    const std::vector<float> alone3 = conv2d(one, w, k.stride).to_vector();
    const std::vector<float> in_batch = slice(batch2, 0, 1, 2).to_vector();
    const std::string what = "conv " + std::to_string(k.c) + " -> " + std::to_string(k.o) + " on " +
                             std::to_string(k.size) + "^2";
    EXPECT_EQ(alone2, alone1) << what;
    EXPECT_EQ(alone3, alone1) << what;
    EXPECT_EQ(in_batch, alone1) << what;
  }
  set_num_threads(saved);
}

TEST(Parallel, ParallelForCoversTheRangeInFixedChunks) {
  const int saved = num_threads();
  set_num_threads(3);
  std::vector<int> owner(10, -1);
  parallel_for(10, [&](int chunk, std::int64_t begin, std::int64_t end) {
    for (std::int64_t i = begin; i < end; ++i)
      owner[static_cast<std::size_t>(i)] = chunk;
  });
  EXPECT_EQ(owner, (std::vector<int>{0, 0, 0, 1, 1, 1, 2, 2, 2, 2}));
  EXPECT_THROW(set_num_threads(0), std::invalid_argument);
  // an exception in a chunk reaches the caller instead of terminating the process
  set_num_threads(2);
  EXPECT_THROW(parallel_for(4,
                            [](int chunk, std::int64_t, std::int64_t) {
                              if (chunk == 1)
                                throw std::runtime_error("chunk 1 failed");
                            }),
               std::runtime_error);
  set_num_threads(saved);
}

// set_num_threads from another thread while kernels run: each kernel keeps the block and
// chunk counts it sized its buffers with (before, a count that grew between sizing and
// splitting wrote past the buffers), and every thread count gives the same bits
TEST(Parallel, SetNumThreadsWhileKernelsRunIsSafe) {
  const int saved = num_threads();
  const std::vector<float> reference = loss_and_gradients(1);
  std::atomic<bool> done{false};
  std::thread changer([&] {
    for (int i = 0; !done.load(); ++i)
      set_num_threads(1 + i % 3);
  });
  for (int run = 0; run < 40; ++run)
    ASSERT_EQ(loss_and_gradients_at_current_threads(), reference) << "run " << run;
  done = true;
  changer.join();
  set_num_threads(saved);
}

}  // namespace
}  // namespace ropes::nn
