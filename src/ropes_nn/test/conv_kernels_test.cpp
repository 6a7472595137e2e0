// The convolutions' kernels (src/conv_kernels.hpp) build each image's im2col matrix a tile
// at a time. The witness is the same kernel with the matrix built whole (one product per
// image, as gemm() blocks it): the tiles must give the same bits, at every thread count, for
// stride 1 and 2, SAME, VALID and uneven padding, tiles that end mid-row, and sums over
// pixels long enough to be split.
#include <gtest/gtest.h>

#include <string>
#include <vector>

#include "conv_kernels.hpp"
#include "gemm.hpp"
#include "ropes_core/philox.hpp"
#include "ropes_nn/ops.hpp"
#include "ropes_nn/parallel.hpp"

namespace ropes::nn {
namespace {

std::vector<float> normals(std::int64_t n, std::uint64_t seed) {
  core::PhiloxStream rng(seed, 0);
  std::vector<float> v(static_cast<std::size_t>(n));
  for (float& x : v)
    x = static_cast<float>(rng.normal());
  return v;
}

struct Case {
  std::int64_t n, c, h, w, o, k;
  int stride, top, left, bottom, right;
};

ConvGeometry geometry(const Case& c) {
  ConvGeometry g{c.n, c.c, c.h, c.w, c.o, c.k, c.k, 0, 0, c.stride, c.top, c.left};
  g.oh = (c.h + c.top + c.bottom - c.k) / c.stride + 1;
  g.ow = (c.w + c.left + c.right - c.k) / c.stride + 1;
  return g;
}

std::vector<float> values(const Buffer& b) {
  return std::vector<float>(b.begin(), b.end());
}

// AE1's layers at x1/8 (8 channels at 128x128, stride-2 down to 64x64), a batch of one (the
// latency path) and of three, a 5x5 VALID and an uneven explicit padding, a 1x1 convolution,
// one product too small for the blocked kernel (one output channel), an LDR layer (6x6 VALID,
// one tile an image: the weights packed once for many), weights too deep to pack once, and one
// small image (one tile: its whole product and im2col shared by the threads)
const Case kCases[] = {
    {3, 8, 128, 128, 8, 3, 1, 1, 1, 1, 1},
    {1, 8, 128, 128, 16, 3, 1, 1, 1, 1, 1},
    {2, 8, 128, 128, 8, 3, 2, 0, 0, 1, 1},
    {2, 3, 37, 45, 5, 5, 1, 0, 0, 0, 0},
    {2, 4, 40, 33, 6, 3, 2, 2, 0, 1, 3},
    {2, 16, 30, 30, 12, 1, 1, 0, 0, 0, 0},
    {2, 1, 128, 128, 8, 3, 1, 1, 1, 1, 1},
    {2, 8, 20, 20, 1, 3, 1, 1, 1, 1, 1},
    {17, 32, 6, 6, 64, 3, 1, 0, 0, 0, 0},
    {9, 130, 10, 10, 40, 3, 1, 1, 1, 1, 1},
    {1, 8, 12, 12, 16, 3, 1, 1, 1, 1, 1},
    // stride 1 with rows of whole 16-pixel vectors, for the v4 level's direct kernel: 48+32
    // pixels (a 2-packet panel), 256 and 1024 (a last 1-packet panel; sums of 18, 9 and 72
    // terms: 16 + 2, 8 + 1 and 72 + 0 in the even/odd split), 5x5 taps with padding 2
    {2, 2, 5, 16, 4, 3, 1, 1, 1, 1, 1},
    {2, 1, 16, 16, 12, 3, 1, 1, 1, 1, 1},
    {2, 8, 32, 32, 8, 3, 1, 1, 1, 1, 1},
    {3, 3, 4, 32, 4, 5, 1, 2, 2, 2, 2},
};

TEST(ConvKernels, TilesGiveTheWholeImagesBitsAtEveryThreadCount) {
  const int saved = num_threads();
  for (const Case& c : kCases) {
    const ConvGeometry g = geometry(c);
    const std::vector<float> x = normals(g.x_shape().numel(), 1);
    const std::vector<float> w = normals(g.w_shape().numel(), 2);
    const std::vector<float> gy = normals(g.y_shape().numel(), 3);
    const std::string what = "x " + g.x_shape().str() + " w " + g.w_shape().str() + " stride " +
                             std::to_string(g.stride);
    set_num_threads(1);
    const auto y = values(conv_forward(x.data(), w.data(), g, ConvTiling::kWholeImages));
    const auto dx = values(conv_input_grad(gy.data(), w.data(), g, ConvTiling::kWholeImages));
    const auto dw = values(conv_weight_grad(x.data(), gy.data(), g, ConvTiling::kWholeImages));
    for (int threads : {1, 2, 3}) {
      set_num_threads(threads);
      const std::string at = what + " at " + std::to_string(threads) + " thread(s)";
      EXPECT_EQ(values(conv_forward(x.data(), w.data(), g)), y) << "forward, " << at;
      EXPECT_EQ(values(conv_input_grad(gy.data(), w.data(), g)), dx) << "input grad, " << at;
      EXPECT_EQ(values(conv_weight_grad(x.data(), gy.data(), g)), dw) << "weight grad, " << at;
    }
  }
  set_num_threads(saved);
}

// The whole-image kernels against the definition: an im2col matrix built element by element
// here (im2col[(ch, ki, kj)][(oy, ox)] = x[ch][oy * stride - top + ki][ox * stride - left + kj],
// zero outside the image) and the same gemm(), bit for bit; col2im likewise, each input pixel
// summing its terms in (ki, kj) order from 0. Rows of 1 to 21 pixels and every padding and
// stride exercise the copies' vector and remainder paths.
TEST(ConvKernels, WholeImagesAreIm2colByDefinitionThenTheProduct) {
  const int saved = num_threads();
  set_num_threads(1);
  for (std::int64_t width : {1, 3, 7, 8, 9, 13, 16, 17, 21}) {
    for (int stride : {1, 2, 3}) {
      for (int pad : {0, 1, 2}) {
        const Case c{2, 3, 5, width, 4, 3, stride, pad, pad, pad, 2 * pad};
        const ConvGeometry g = geometry(c);
        if (g.oh < 1 || g.ow < 1)
          continue;
        const std::vector<float> x = normals(g.x_shape().numel(), 4);
        const std::vector<float> w = normals(g.w_shape().numel(), 5);
        const std::vector<float> gy = normals(g.y_shape().numel(), 6);
        const std::int64_t patch = g.patch(), pixels = g.pixels(), image = g.c * g.h * g.w;
        std::vector<float> y(static_cast<std::size_t>(g.y_shape().numel()));
        std::vector<float> dx(static_cast<std::size_t>(g.x_shape().numel()), 0.0f);
        // f(entry of image i's im2col matrix, the element of x it reads, or -1 outside the image)
        const auto each_entry = [&](std::int64_t i, const auto& f) {
          for (std::int64_t ch = 0; ch < g.c; ++ch)
            for (std::int64_t ki = 0; ki < g.kh; ++ki)
              for (std::int64_t kj = 0; kj < g.kw; ++kj)
                for (std::int64_t oy = 0; oy < g.oh; ++oy)
                  for (std::int64_t ox = 0; ox < g.ow; ++ox) {
                    const std::int64_t iy = oy * g.stride - g.top + ki;
                    const std::int64_t ix = ox * g.stride - g.left + kj;
                    const bool inside = iy >= 0 && iy < g.h && ix >= 0 && ix < g.w;
                    f(static_cast<std::size_t>(((ch * g.kh + ki) * g.kw + kj) * pixels + oy * g.ow +
                                               ox),
                      inside ? i * image + (ch * g.h + iy) * g.w + ix : std::int64_t{-1});
                  }
        };
        for (std::int64_t i = 0; i < g.n; ++i) {
          std::vector<float> col(static_cast<std::size_t>(patch * pixels));
          each_entry(i, [&](std::size_t entry, std::int64_t at) {
            col[entry] = at >= 0 ? x[static_cast<std::size_t>(at)] : 0.0f;
          });
          gemm(w.data(), col.data(), y.data() + i * g.o * pixels, g.o, patch, pixels);
          // the adjoint: col = w^T gy_i, each term added into its input pixel
          gemm(w.data(), true, gy.data() + i * g.o * pixels, false, col.data(), patch, g.o, pixels,
               false);
          each_entry(i, [&](std::size_t entry, std::int64_t at) {
            if (at >= 0)
              dx[static_cast<std::size_t>(at)] += col[entry];
          });
        }
        const std::string what = "x " + g.x_shape().str() + " stride " + std::to_string(stride) +
                                 " padding " + std::to_string(pad);
        EXPECT_EQ(values(conv_forward(x.data(), w.data(), g, ConvTiling::kWholeImages)), y) << what;
        EXPECT_EQ(values(conv_input_grad(gy.data(), w.data(), g, ConvTiling::kWholeImages)), dx)
            << what;
      }
    }
  }
  set_num_threads(saved);
}

// The v4 level's direct kernel takes the padded image of a stride-1 convolution whose output
// rows are whole 16-pixel vectors and whose output channels come in fours (else the tests
// above would not see it), and declines the rest
TEST(ConvKernels, TheV4LevelsDirectKernelCoversStrideOneRowsOfWholeVectors) {
  if (std::string(gemm_kernels().level).rfind("x86-64-v4", 0) != 0)
    GTEST_SKIP() << "the kernels in use are " << gemm_kernels().level << ", not v4";
  struct Padded {
    std::int64_t c, h, w, o, ow;
    bool covered;
  };
  // a 3x3 window over an image already padded: ow = w - 2 where it fits
  for (const Padded& c : {Padded{2, 7, 18, 4, 16, true}, Padded{1, 18, 18, 12, 16, true},
                          Padded{2, 7, 18, 5, 16, false}, Padded{2, 7, 14, 4, 12, false}}) {
    const std::vector<float> x = normals(c.c * c.h * c.w, 1);
    const std::vector<float> w = normals(c.o * c.c * 9, 2);
    const std::int64_t pixels = (c.h - 2) * c.ow;
    std::vector<float> y(static_cast<std::size_t>(c.o * pixels));
    const ConvTile tile{x.data(), c.c,      c.h,     c.w, 3,        3,      0, 0,
                        c.ow,     w.data(), nullptr, c.o, y.data(), pixels, 0, pixels};
    EXPECT_EQ(gemm_conv_tile_covers(tile), c.covered) << c.c << "x" << c.h << "x" << c.w;
    EXPECT_EQ(gemm_conv_tile(tile), c.covered) << c.c << "x" << c.h << "x" << c.w << " to " << c.o;
  }
}

// sums over nothing (no channels, no images, no output pixels) are zeros, not a crash
TEST(ConvKernels, EmptySumsAreZeros) {
  const std::vector<float> x(64, 1.0f), w(64, 1.0f), gy(64, 1.0f);
  ConvGeometry no_channels{2, 0, 8, 8, 4, 3, 3, 8, 8, 1, 1, 1};
  const Buffer y = conv_forward(x.data(), w.data(), no_channels);
  EXPECT_EQ(values(y), std::vector<float>(2 * 4 * 8 * 8, 0.0f));
  ConvGeometry no_images{0, 3, 8, 8, 4, 3, 3, 8, 8, 1, 1, 1};
  EXPECT_EQ(values(conv_weight_grad(x.data(), gy.data(), no_images)),
            std::vector<float>(4 * 3 * 3 * 3, 0.0f));
  EXPECT_TRUE(conv_forward(x.data(), w.data(), no_images).empty());
  ConvGeometry no_pixels{2, 3, 0, 0, 4, 3, 3, 0, 0, 1, 1, 1};
  EXPECT_EQ(values(conv_weight_grad(x.data(), gy.data(), no_pixels)),
            std::vector<float>(4 * 3 * 3 * 3, 0.0f));
}

// conv2d with a bias, where no graph is recorded, starts each output's sum at the bias; the
// witness is the product with the bias added after (what the graph records), bit for bit
TEST(ConvKernels, ABiasInTheProductIsTheBiasAddedAfter) {
  const int saved = num_threads();
  for (const Case& c : kCases) {
    const ConvGeometry g = geometry(c);
    const Tensor x(g.x_shape(), normals(g.x_shape().numel(), 1));
    const Tensor w(g.w_shape(), normals(g.w_shape().numel(), 2));
    const Tensor b(Shape{g.o}, normals(g.o, 3));
    const Padding2d pads = Padding2d::explicit_pads(c.top, c.bottom, c.left, c.right);
    for (int threads : {1, 2}) {
      set_num_threads(threads);
      const Tensor after = add(conv2d(x, w, c.stride, pads), reshape(b, Shape{1, g.o, 1, 1}));
      const Tensor fused = conv2d(x, w, b, c.stride, pads);
      EXPECT_EQ(std::vector<float>(fused.data(), fused.data() + fused.numel()),
                std::vector<float>(after.data(), after.data() + after.numel()))
          << "x " << g.x_shape().str() << " w " << g.w_shape().str() << " at " << threads
          << " thread(s)";
    }
  }
  set_num_threads(saved);
  EXPECT_THROW(conv2d(Tensor(Shape{1, 2, 4, 4}, std::vector<float>(32)),
                      Tensor(Shape{3, 2, 3, 3}, std::vector<float>(54)),
                      Tensor(Shape{2}, std::vector<float>(2))),
               std::invalid_argument);
}

}  // namespace
}  // namespace ropes::nn
