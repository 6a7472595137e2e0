// conv2d and conv_transpose2d on three kernels that are closed under differentiation:
//   y  = conv(x, w)                 forward
//   dx = conv_input_grad(g, w)      the adjoint in x (also conv_transpose2d)
//   dw = conv_weight_grad(x, g)     the adjoint in w
// Each one's backward is written with the other two, so gradients of gradients work.

#include <omp.h>
#ifdef __AVX__
#include <immintrin.h>
#endif

#include <algorithm>
#include <atomic>
#include <memory>
#include <stdexcept>
#include <string>

#include "conv_kernels.hpp"
#include "gemm.hpp"
#include "ropes_nn/ops.hpp"
#include "ropes_nn/parallel.hpp"
#include "tensor_impl.hpp"

namespace ropes::nn {

namespace {

// the output columns [begin, end) of one kernel column kj whose input pixel is inside the
// image: ix = ox * stride - left + kj in [0, w)
void inside_range(const ConvGeometry& g, std::int64_t kj, std::int64_t* begin, std::int64_t* end) {
  const std::int64_t offset = kj - g.left;  // ix = ox * stride + offset
  std::int64_t b = offset >= 0 ? 0 : (-offset + g.stride - 1) / g.stride;
  std::int64_t e = g.w - offset <= 0 ? 0 : (g.w - offset + g.stride - 1) / g.stride;
  b = std::min(b, g.ow);
  e = std::max(b, std::min(e, g.ow));
  *begin = b;
  *end = e;
}

// The runs of im2col and col2im are an image row or less: too short for memcpy and memset to pay
// for their calls, and long enough that a loop's scalar remainder costs more than its vectors.
// With AVX, whole 8-float vectors, the last one overlapping the one before where the length is
// not a multiple (a copy writes each element's value, whichever store wrote it last).
inline void copy_run(const float* in, float* out, std::int64_t n) {
#ifdef __AVX__
  if (n >= 8) {
    std::int64_t j = 0;
    for (; j + 8 <= n; j += 8)
      _mm256_storeu_ps(out + j, _mm256_loadu_ps(in + j));
    if (j < n)
      _mm256_storeu_ps(out + n - 8, _mm256_loadu_ps(in + n - 8));
    return;
  }
#endif
  for (std::int64_t j = 0; j < n; ++j)
    out[j] = in[j];
}

inline void zero_run(float* out, std::int64_t n) {
#ifdef __AVX__
  if (n >= 8) {
    std::int64_t j = 0;
    for (; j + 8 <= n; j += 8)
      _mm256_storeu_ps(out + j, _mm256_setzero_ps());
    if (j < n)
      _mm256_storeu_ps(out + n - 8, _mm256_setzero_ps());
    return;
  }
#endif
  for (std::int64_t j = 0; j < n; ++j)
    out[j] = 0.0f;
}

// out[j] += in[j]: the same addition per element as the plain loop, eight at a time, the last
// few under a mask
inline void add_run(const float* in, float* out, std::int64_t n) {
  std::int64_t j = 0;
#ifdef __AVX2__
  for (; j + 8 <= n; j += 8)
    _mm256_storeu_ps(out + j, _mm256_add_ps(_mm256_loadu_ps(out + j), _mm256_loadu_ps(in + j)));
  if (j < n) {
    const __m256i mask = _mm256_cmpgt_epi32(_mm256_set1_epi32(static_cast<int>(n - j)),
                                            _mm256_setr_epi32(0, 1, 2, 3, 4, 5, 6, 7));
    _mm256_maskstore_ps(
        out + j, mask,
        _mm256_add_ps(_mm256_maskload_ps(out + j, mask), _mm256_maskload_ps(in + j, mask)));
    return;
  }
#endif
  for (; j < n; ++j)
    out[j] += in[j];
}

// x [c, h, w] padded for a stride-1 convolution's direct kernel: [c, oh + kh - 1, ow + kw - 1],
// the image at (top, left) and zeros around it (what im2col reads outside the image), so that
// every window lies inside
void pad_image(const float* x, const ConvGeometry& g, float* out) {
  const std::int64_t hp = g.oh + g.kh - 1, wp = g.ow + g.kw - 1;
  const std::int64_t b = std::clamp<std::int64_t>(g.left, 0, wp);
  const std::int64_t e = std::clamp<std::int64_t>(g.left + g.w, b, wp);
  for (std::int64_t ch = 0; ch < g.c; ++ch)
    for (std::int64_t r = 0; r < hp; ++r) {
      float* row = out + (ch * hp + r) * wp;
      const std::int64_t iy = r - g.top;
      if (iy < 0 || iy >= g.h) {
        zero_run(row, wp);
        continue;
      }
      zero_run(row, b);
      copy_run(x + (ch * g.h + iy) * g.w + (b - g.left), row + b, e - b);
      zero_run(row + e, wp - e);
    }
}

// x [c, h, w] -> the columns of output pixels [p0, p1) of the im2col matrix
// [c*kh*kw, oh*ow], into col with row stride ld (column p0 first), zeros where the window
// leaves the image
void im2col(const float* x, const ConvGeometry& g, float* col, std::int64_t ld, std::int64_t p0,
            std::int64_t p1) {
  if (p0 >= p1)
    return;
  const std::int64_t oy_first = p0 / g.ow, oy_last = (p1 - 1) / g.ow;
  for (std::int64_t kj = 0; kj < g.kw; ++kj) {
    std::int64_t in_begin = 0, in_end = 0;
    inside_range(g, kj, &in_begin, &in_end);
    const std::int64_t offset = kj - g.left;
    for (std::int64_t ch = 0; ch < g.c; ++ch)
      for (std::int64_t ki = 0; ki < g.kh; ++ki) {
        // column P of this patch row is col[row + P]
        const std::int64_t row = ((ch * g.kh + ki) * g.kw + kj) * ld - p0;
        for (std::int64_t oy = oy_first; oy <= oy_last; ++oy) {
          // this output row's columns within [p0, p1), from `out`
          const std::int64_t first = std::max(oy * g.ow, p0) - oy * g.ow;
          const std::int64_t last = std::min(oy * g.ow + g.ow, p1) - oy * g.ow;
          float* out = col + (row + oy * g.ow + first);
          const std::int64_t iy = oy * g.stride - g.top + ki;
          if (iy < 0 || iy >= g.h) {
            zero_run(out, last - first);
            continue;
          }
          const std::int64_t b = std::clamp(in_begin, first, last);
          const std::int64_t e = std::clamp(in_end, b, last);
          zero_run(out, b - first);
          if (e > b) {
            // input column b * stride + offset >= 0 of row iy
            const float* in = x + ((ch * g.h + iy) * g.w + b * g.stride + offset);
            float* run = out + (b - first);
            if (g.stride == 1) {
              copy_run(in, run, e - b);
            } else if (g.stride == 2) {
              // a constant stride, which the compiler vectorises (even lanes of two loads)
              for (std::int64_t j = 0; j < e - b; ++j)
                run[j] = in[2 * j];
            } else {
              for (std::int64_t j = 0; j < e - b; ++j)
                run[j] = in[j * g.stride];
            }
          }
          zero_run(out + (e - first), last - e);
        }
      }
  }
}

// the adjoint of im2col: the columns of output pixels [p0, p1) of col (row stride ld,
// column p0 first) added into x [c, h, w]. Each element of x receives its terms in the order
// of (ki, kj), which is the descending order of the output pixel they come from: tiles of
// pixels added last to first give every element the sums of the whole matrix at once.
void col2im(const float* col, std::int64_t ld, const ConvGeometry& g, float* x, std::int64_t p0,
            std::int64_t p1) {
  if (p0 >= p1)
    return;
  const std::int64_t oy_first = p0 / g.ow, oy_last = (p1 - 1) / g.ow;
  for (std::int64_t ch = 0; ch < g.c; ++ch)
    for (std::int64_t ki = 0; ki < g.kh; ++ki)
      for (std::int64_t kj = 0; kj < g.kw; ++kj) {
        std::int64_t in_begin = 0, in_end = 0;
        inside_range(g, kj, &in_begin, &in_end);
        const std::int64_t offset = kj - g.left;
        // column P of this patch row is col[row + P]
        const std::int64_t row = ((ch * g.kh + ki) * g.kw + kj) * ld - p0;
        for (std::int64_t oy = oy_first; oy <= oy_last; ++oy) {
          const std::int64_t iy = oy * g.stride - g.top + ki;
          if (iy < 0 || iy >= g.h)
            continue;
          const std::int64_t first = std::max(oy * g.ow, p0) - oy * g.ow;
          const std::int64_t last = std::min(oy * g.ow + g.ow, p1) - oy * g.ow;
          const std::int64_t b = std::clamp(in_begin, first, last);
          const std::int64_t e = std::clamp(in_end, b, last);
          if (e <= b)
            continue;
          // output columns [b, e) of row oy, into input columns b * stride + offset >= 0 on
          float* out = x + ((ch * g.h + iy) * g.w + b * g.stride + offset);
          const float* in = col + (row + oy * g.ow + b);
          if (g.stride == 1) {
            add_run(in, out, e - b);
          } else {
            for (std::int64_t j = 0; j < e - b; ++j)
              out[j * g.stride] += in[j];
          }
        }
      }
}

std::atomic<std::uint64_t> g_flops{0};

void count_flops(const ConvGeometry& g) {
  add_flops(static_cast<std::uint64_t>(2 * g.n * g.o * g.patch() * g.pixels()));
}

// This thread's im2col buffer for the forward pass, which only grows. From the pool, blocks
// of one size held by several threads at once would number what the threads' timing made
// them: a warm inference call could then still allocate (estimator_frame_test at 3 threads
// on 2 cores saw it). Each thread's work, and so its largest buffer, is fixed.
float* forward_scratch(std::size_t size) {
  thread_local Buffer scratch;
  if (scratch.size() < size)
    scratch = Buffer(size);
  return scratch.data();
}

// This thread's padded image for the direct kernel, which only grows (as forward_scratch)
float* padded_scratch(std::size_t size) {
  thread_local Buffer scratch;
  if (scratch.size() < size)
    scratch = Buffer(size);
  return scratch.data();
}

std::int64_t tiles_of(std::int64_t size, std::int64_t tile) {
  return (size + tile - 1) / tile;
}

}  // namespace

// y_i [o, pixels] = w [o, patch] * col_i [patch, pixels], a tile of columns at a time. The
// threads take contiguous runs of (image, tile) pairs, so one image's tiles are shared when
// the images are fewer than the threads (one frame's latency).
Buffer conv_forward(const float* x, const float* w, const ConvGeometry& g, ConvTiling tiling,
                    const float* bias) {
  count_flops(g);
  Buffer y(static_cast<std::size_t>(g.y_shape().numel()));
  const std::int64_t m = g.o, k = g.patch(), n = g.pixels(), image = g.c * g.h * g.w;
  const bool blocked = tiling == ConvTiling::kTiles && gemm_is_blocked(m, k, n);
  const GemmBlocking blocking = blocked ? gemm_blocking(m, k, n) : GemmBlocking{k, n, m};
  const std::int64_t tile = blocking.mc, tiles = blocked ? tiles_of(n, tile) : 1;
  // one image of fewer tiles than threads, or a product too small for the blocked kernel:
  // the whole-image product, whose rows (or columns) gemm() shares out when it is one image
  // outside a parallel region, as is then its im2col matrix, by columns
  const bool share_images = g.n == 1 && !omp_in_parallel();
  if (!blocked || (share_images && tiles < num_threads())) {
    parallel_for(g.n, [&](int, std::int64_t begin, std::int64_t end) {
      float* col = forward_scratch(static_cast<std::size_t>(k * n));
      for (std::int64_t i = begin; i < end; ++i) {
        const float* xi = x + i * image;
        if (share_images) {
          parallel_for(n, [&](int, std::int64_t p0, std::int64_t p1) {
            im2col(xi, g, col + p0, n, p0, p1);
          });
        } else {
          im2col(xi, g, col, n, 0, n);
        }
        float* yi = y.data() + i * m * n;
        gemm(w, col, yi, m, k, n);
        if (bias != nullptr) {
          for (std::int64_t r = 0; r < m; ++r)
            for (std::int64_t j = 0; j < n; ++j)
              yi[r * n + j] = yi[r * n + j] + bias[r];
        }
      }
    });
    return y;
  }
  // a stride-1 convolution's padded image for the level's direct kernel
  const std::int64_t hp = g.oh + g.kh - 1, wp = g.ow + g.kw - 1;
  parallel_for(g.n * tiles, [&](int, std::int64_t begin, std::int64_t end) {
    float* col = forward_scratch(static_cast<std::size_t>(k * std::min(tile, n)));
    GemmSharedA weights(blocking, w, false, k, m, k);  // packed once for the thread's tiles
    // the level's direct kernel where it covers the tile: the same bits without im2col, from
    // the image padded once (and only when the kernel takes it)
    const bool direct = g.stride == 1 && weights.packed();
    float* padded = direct ? padded_scratch(static_cast<std::size_t>(g.c * hp * wp)) : nullptr;
    std::int64_t padded_image = -1;
    for (std::int64_t item = begin; item < end; ++item) {
      const std::int64_t i = item / tiles, p0 = item % tiles * tile, p1 = std::min(p0 + tile, n);
      const ConvTile direct_tile{
          padded, g.c, hp,     wp, g.kh, g.kw, 0, 0, g.ow, w, bias, m, y.data() + i * m * n,
          n,      p0,  p1 - p0};
      if (direct && gemm_conv_tile_covers(direct_tile)) {
        if (padded_image != i)
          pad_image(x + i * image, g, padded);
        padded_image = i;
        gemm_conv_tile(direct_tile);
        continue;
      }
      im2col(x + i * image, g, col, p1 - p0, p0, p1);
      float* yi = y.data() + i * m * n + p0;
      if (bias != nullptr)
        weights.multiply_onto(bias, col, p1 - p0, yi, n, p1 - p0);
      else
        weights.multiply(col, p1 - p0, yi, n, p1 - p0, false);
    }
  });
  return y;
}

// col_i [patch, pixels] = w^T [patch, o] * gy_i [o, pixels], then col2im: a tile of columns
// at a time, last to first (see col2im), one image per thread
Buffer conv_input_grad(const float* gy, const float* w, const ConvGeometry& g, ConvTiling tiling) {
  count_flops(g);
  Buffer dx(static_cast<std::size_t>(g.x_shape().numel()));
  const std::int64_t m = g.patch(), k = g.o, n = g.pixels(), image = g.c * g.h * g.w;
  // one image: the whole-image product, whose rows gemm() shares out
  if (tiling == ConvTiling::kWholeImages || !gemm_is_blocked(m, k, n) ||
      (g.n == 1 && !omp_in_parallel())) {
    parallel_for(g.n, [&](int, std::int64_t begin, std::int64_t end) {
      Buffer col(static_cast<std::size_t>(m * n));
      for (std::int64_t i = begin; i < end; ++i) {
        gemm(w, true, gy + i * k * n, false, col.data(), m, k, n, false);
        float* dxi = dx.data() + i * image;
        std::fill(dxi, dxi + image, 0.0f);
        col2im(col.data(), n, g, dxi, 0, n);
      }
    });
    return dx;
  }
  const GemmBlocking blocking = gemm_blocking(m, k, n);
  const std::int64_t tile = blocking.mc, tiles = tiles_of(n, tile);
  parallel_for(g.n, [&](int, std::int64_t begin, std::int64_t end) {
    Buffer col(static_cast<std::size_t>(m * std::min(tile, n)));
    GemmSharedA weights(blocking, w, true, m, m, k);  // w^T, packed once for the thread
    for (std::int64_t i = begin; i < end; ++i) {
      float* dxi = dx.data() + i * image;
      std::fill(dxi, dxi + image, 0.0f);
      for (std::int64_t t = tiles - 1; t >= 0; --t) {
        const std::int64_t p0 = t * tile, p1 = std::min(p0 + tile, n);
        weights.multiply(gy + i * k * n + p0, n, col.data(), p1 - p0, p1 - p0, false);
        col2im(col.data(), p1 - p0, g, dxi, p0, p1);
      }
    }
  });
  return dx;
}

// dw [o, patch] += gy_i [o, pixels] * col_i^T [pixels, patch], a block of the sum over pixels
// at a time, in order. One partial sum per reduction block of the batch (fixed by the batch
// size), added in block order: the same bits at every thread count.
Buffer conv_weight_grad(const float* x, const float* gy, const ConvGeometry& g, ConvTiling tiling) {
  count_flops(g);
  const std::int64_t m = g.o, k = g.pixels(), n = g.patch(), image = g.c * g.h * g.w;
  const std::size_t w_size = static_cast<std::size_t>(m * n);
  if (g.n == 0 || k == 0 || n == 0)
    return Buffer(w_size, 0.0f);  // an empty sum
  // one image: the whole-image product, whose rows gemm() shares out (a tile of the sum
  // runs on one thread)
  const bool whole = tiling == ConvTiling::kWholeImages || !gemm_is_blocked(m, k, n) ||
                     (g.n == 1 && !omp_in_parallel());
  const GemmBlocking blocking = whole ? GemmBlocking{k, n, m} : gemm_blocking(m, k, n);
  const std::int64_t tile = whole ? k : blocking.kc, tiles = tiles_of(k, tile);
  // each block's partial sum is made (zeroed) by the thread that computes it
  std::vector<Buffer> partial(static_cast<std::size_t>(reduction_blocks(g.n)));
  for_each_reduction_block(g.n, [&](int block, std::int64_t begin, std::int64_t end) {
    Buffer col(static_cast<std::size_t>(n * std::min(tile, k)));
    partial[static_cast<std::size_t>(block)] = Buffer(w_size, 0.0f);
    float* dw = partial[static_cast<std::size_t>(block)].data();
    for (std::int64_t i = begin; i < end; ++i) {
      if (whole) {
        im2col(x + i * image, g, col.data(), k, 0, k);
        gemm(gy + i * m * k, false, col.data(), true, dw, m, k, n, true);
        continue;
      }
      for (std::int64_t t = 0; t < tiles; ++t) {
        const std::int64_t p0 = t * tile, p1 = std::min(p0 + tile, k);
        im2col(x + i * image, g, col.data(), p1 - p0, p0, p1);
        gemm_tile(blocking, gy + i * m * k + p0, false, k, col.data(), true, p1 - p0, dw, n, m,
                  p1 - p0, n, true);
      }
    }
  });
  // the blocks added in order, element by element (the elements split over threads)
  float* total = partial[0].data();
  const auto add_blocks = [&](std::int64_t begin, std::int64_t end) {
    for (std::size_t c = 1; c < partial.size(); ++c) {
      const float* part = partial[c].data();
      for (std::int64_t j = begin; j < end; ++j)
        total[j] += part[j];
    }
  };
  const std::int64_t size = static_cast<std::int64_t>(w_size);
  if (size * static_cast<std::int64_t>(partial.size()) < (1 << 16))
    add_blocks(0, size);
  else
    parallel_for(size, [&](int, std::int64_t begin, std::int64_t end) { add_blocks(begin, end); });
  return std::move(partial[0]);
}

namespace {

Tensor conv_op(const Tensor& x, const Tensor& w, const ConvGeometry& g);
Tensor conv_input_grad_op(const Tensor& gy, const Tensor& w, const ConvGeometry& g);
Tensor conv_weight_grad_op(const Tensor& x, const Tensor& gy, const ConvGeometry& g);

// nodes: each backward is written with the three ops
class ConvNode final : public Node {
 public:
  explicit ConvNode(const ConvGeometry& g) : g_(g) {}
  const char* name() const override { return "conv2d"; }
  std::vector<Tensor> backward(const Tensor& gy) override {
    std::vector<Tensor> r(2);
    if (input_grad_wanted(inputs[0]))
      r[0] = conv_input_grad_op(gy, inputs[1], g_);
    if (input_grad_wanted(inputs[1]))
      r[1] = conv_weight_grad_op(inputs[0], gy, g_);
    return r;
  }

 private:
  ConvGeometry g_;
};

class ConvInputGradNode final : public Node {
 public:
  explicit ConvInputGradNode(const ConvGeometry& g) : g_(g) {}
  const char* name() const override { return "conv2d_input_grad"; }
  // inputs: gy, w; the upstream gradient h has x's shape
  std::vector<Tensor> backward(const Tensor& h) override {
    std::vector<Tensor> r(2);
    if (input_grad_wanted(inputs[0]))
      r[0] = conv_op(h, inputs[1], g_);
    if (input_grad_wanted(inputs[1]))
      r[1] = conv_weight_grad_op(h, inputs[0], g_);
    return r;
  }

 private:
  ConvGeometry g_;
};

class ConvWeightGradNode final : public Node {
 public:
  explicit ConvWeightGradNode(const ConvGeometry& g) : g_(g) {}
  const char* name() const override { return "conv2d_weight_grad"; }
  // inputs: x, gy; the upstream gradient h has w's shape
  std::vector<Tensor> backward(const Tensor& h) override {
    std::vector<Tensor> r(2);
    if (input_grad_wanted(inputs[0]))
      r[0] = conv_input_grad_op(inputs[1], h, g_);
    if (input_grad_wanted(inputs[1]))
      r[1] = conv_op(inputs[0], h, g_);
    return r;
  }

 private:
  ConvGeometry g_;
};

// the node and the input list only when a graph is recorded (see needs_graph)
template <typename NodeType>
Tensor conv_result(const Shape& shape, Buffer values, const ConvGeometry& g, const Tensor& a,
                   const Tensor& b) {
  if (!needs_graph({a, b}))
    return Tensor(shape, std::move(values));
  return make_op_result(shape, std::move(values), std::make_shared<NodeType>(g), {a, b});
}

Tensor conv_op(const Tensor& x, const Tensor& w, const ConvGeometry& g) {
  return conv_result<ConvNode>(g.y_shape(), conv_forward(x.data(), w.data(), g), g, x, w);
}
Tensor conv_input_grad_op(const Tensor& gy, const Tensor& w, const ConvGeometry& g) {
  return conv_result<ConvInputGradNode>(g.x_shape(), conv_input_grad(gy.data(), w.data(), g), g, gy,
                                        w);
}
Tensor conv_weight_grad_op(const Tensor& x, const Tensor& gy, const ConvGeometry& g) {
  return conv_result<ConvWeightGradNode>(g.w_shape(), conv_weight_grad(x.data(), gy.data(), g), g,
                                         x, gy);
}

[[noreturn]] void fail(const char* op, const std::string& what) {
  throw std::invalid_argument(std::string(op) + ": " + what);
}

// padding of one spatial axis of a forward convolution from `in` pixels; returns the
// output size, sets the padding before it
std::int64_t resolve_axis(const char* op, const Padding2d& p, bool vertical, std::int64_t in,
                          std::int64_t k, int stride, int* before) {
  std::int64_t out = 0;
  switch (p.mode) {
    case Padding2d::Mode::kSame: {
      out = (in + stride - 1) / stride;
      const std::int64_t total = std::max<std::int64_t>((out - 1) * stride + k - in, 0);
      *before = static_cast<int>(total / 2);
      break;
    }
    case Padding2d::Mode::kValid:
      *before = 0;
      out = in >= k ? (in - k) / stride + 1 : 0;
      break;
    case Padding2d::Mode::kExplicit: {
      const int a = vertical ? p.top : p.left;
      const int b = vertical ? p.bottom : p.right;
      if (a < 0 || b < 0)
        fail(op, "padding must not be negative");
      *before = a;
      out = in + a + b >= k ? (in + a + b - k) / stride + 1 : 0;
      break;
    }
  }
  return out;
}

}  // namespace

void add_flops(std::uint64_t flops) {
  g_flops += flops;
}
std::uint64_t flop_count() {
  return g_flops.load();
}
void reset_flop_count() {
  g_flops = 0;
}

namespace {
ConvGeometry conv2d_geometry(const Tensor& x, const Tensor& w, int stride,
                             const Padding2d& padding);
}  // namespace

Tensor conv2d(const Tensor& x, const Tensor& w, int stride, const Padding2d& padding) {
  return conv_op(x, w, conv2d_geometry(x, w, stride, padding));
}

Tensor conv2d(const Tensor& x, const Tensor& w, const Tensor& b, int stride,
              const Padding2d& padding) {
  const ConvGeometry g = conv2d_geometry(x, w, stride, padding);
  if (!b.defined() || b.shape() != Shape{g.o}) {
    fail("conv2d", "bias " + (b.defined() ? b.shape().str() : std::string("undefined")) +
                       "; expected [" + std::to_string(g.o) + "] for w " + w.shape().str());
  }
  if (needs_graph({x, w, b}))
    return add(conv_op(x, w, g), reshape(b, Shape{1, g.o, 1, 1}));
  return Tensor(g.y_shape(), conv_forward(x.data(), w.data(), g, ConvTiling::kTiles, b.data()));
}

namespace {
ConvGeometry conv2d_geometry(const Tensor& x, const Tensor& w, int stride,
                             const Padding2d& padding) {
  if (!x.defined() || !w.defined())
    fail("conv2d", "undefined input");
  if (x.rank() != 4 || w.rank() != 4 || x.shape()[1] != w.shape()[1]) {
    fail("conv2d", "x " + x.shape().str() + " and w " + w.shape().str() +
                       "; expected [N, C, H, W] and [O, C, KH, KW] with the same C");
  }
  if (stride < 1)
    fail("conv2d", "stride " + std::to_string(stride) + "; expected >= 1");
  ConvGeometry g{x.shape()[0],
                 x.shape()[1],
                 x.shape()[2],
                 x.shape()[3],
                 w.shape()[0],
                 w.shape()[2],
                 w.shape()[3],
                 0,
                 0,
                 stride,
                 0,
                 0};
  g.oh = resolve_axis("conv2d", padding, true, g.h, g.kh, stride, &g.top);
  g.ow = resolve_axis("conv2d", padding, false, g.w, g.kw, stride, &g.left);
  if (g.oh <= 0 || g.ow <= 0) {
    fail("conv2d", "a " + std::to_string(g.kh) + "x" + std::to_string(g.kw) +
                       " kernel leaves no output on x " + x.shape().str());
  }
  return g;
}
}  // namespace

Tensor conv_transpose2d(const Tensor& x, const Tensor& w, int stride, const Padding2d& padding) {
  if (!x.defined() || !w.defined())
    fail("conv_transpose2d", "undefined input");
  if (x.rank() != 4 || w.rank() != 4 || x.shape()[1] != w.shape()[0]) {
    fail("conv_transpose2d", "x " + x.shape().str() + " and w " + w.shape().str() +
                                 "; expected [N, Cin, H, W] and [Cin, Cout, KH, KW]");
  }
  if (stride < 1)
    fail("conv_transpose2d", "stride " + std::to_string(stride) + "; expected >= 1");
  // the forward convolution this is the adjoint of maps [oh, ow] back to x's [h, w]
  const std::int64_t h = x.shape()[2], wd = x.shape()[3], kh = w.shape()[2], kw = w.shape()[3];
  ConvGeometry g{x.shape()[0], w.shape()[1], 0, 0, w.shape()[0], kh, kw, h, wd, stride, 0, 0};
  if (padding.mode == Padding2d::Mode::kSame) {
    g.h = h * stride;
    g.w = wd * stride;
    g.top = static_cast<int>(std::max<std::int64_t>(kh - stride, 0) / 2);
    g.left = static_cast<int>(std::max<std::int64_t>(kw - stride, 0) / 2);
  } else {
    const Padding2d p =
        padding.mode == Padding2d::Mode::kValid ? Padding2d::explicit_pads(0, 0, 0, 0) : padding;
    if (p.top < 0 || p.bottom < 0 || p.left < 0 || p.right < 0) {
      fail("conv_transpose2d", "padding must not be negative");
    }
    g.h = (h - 1) * stride + kh - p.top - p.bottom;
    g.w = (wd - 1) * stride + kw - p.left - p.right;
    g.top = p.top;
    g.left = p.left;
  }
  if (g.h <= 0 || g.w <= 0) {
    fail("conv_transpose2d", "the padding leaves no output for x " + x.shape().str());
  }
  return conv_input_grad_op(x, w, g);
}

}  // namespace ropes::nn
