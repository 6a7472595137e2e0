#pragma once
// Private: the instruction-set-specific half of src/gemm.hpp, compiled once per level
// (gemm_kernel.cpp with -march=x86-64-v3, -march=x86-64-v4, or the baseline's flags).
//
// Only plain types cross this boundary. Each compilation renames Eigen's namespace
// (-DEigen=ropes_eigen_<level>) and puts its own code in ropes::nn::<level>, so that no
// inline function or template instance compiled for one level can be picked by the linker for
// another (a v4 copy of an Eigen routine run on an AVX2 CPU would die of SIGILL); the test
// `ropes_nn_kernel_symbols` checks that the objects define nothing outside those namespaces.
#include <cstdint>

namespace ropes::nn {

struct CacheSizes {
  std::int64_t l1, l2, l3;
};

// one product c (+)= op(a) op(b) (see gemm.hpp), with its blocking and packing blocks
struct GemmProduct {
  const float* a;
  bool a_transposed;
  const float* b;
  bool b_transposed;
  float* c;
  std::int64_t m, k, n;
  bool accumulate;
  std::int64_t kc, mc, nc;     // the blocking of the whole product (Eigen's column-major view)
  std::int64_t lda, ldb, ldc;  // the row strides of a, b and c as stored
  float* block_a;              // kc * mc floats
  float* block_b;              // kc * nc floats
};

// One tile of a stride-1 convolution's forward product (conv.cpp): the output pixels
// [p0, p0 + n) of one image, every output channel, from the image itself (padded by the
// caller where the kernel wants top = left = 0 and every window inside).
struct ConvTile {
  const float* x;  // the image [c, h, w]
  std::int64_t c, h, w, kh, kw, top, left, ow;
  const float* weights;  // [o, c * kh * kw]
  const float* bias;     // [o], or null
  std::int64_t o;
  float* y;  // the image's output [o, pixels]
  std::int64_t pixels, p0, n;
};

struct GemmKernels {
  // the compilation's level: "x86-64-v4", "x86-64-v3", the baseline's ("x86-64", ...), with
  // " (-march=native)" in a native build
  const char* level;
  // rows [row_begin, row_end) and columns [col_begin, col_end) of c, with the blocking of the
  // whole product: each element is computed by the same instructions as in the whole product
  // when rows start at multiples of 16 and columns at multiples of mc (gemm.hpp)
  void (*block)(const GemmProduct& p, std::int64_t row_begin, std::int64_t row_end,
                std::int64_t col_begin, std::int64_t col_end);
  // op(a) packed once into p.block_b (k * m floats) for products that share it (several
  // images' b and c with one a), where its sum fits one block (k <= kc); false (nothing
  // packed) otherwise
  bool (*pack_a)(const GemmProduct& p);
  // all rows and columns of c (+)= op(a) op(b) with op(a) already packed by pack_a: the bits
  // of block(p, 0, m, 0, n); b must not be transposed
  void (*with_packed_a)(const GemmProduct& p);
  // whether conv_tile covers the tile's shape (reads no data: a caller asks before it pads)
  bool (*conv_tile_covers)(const ConvTile& t);
  // the tile of y the blocked product of the tile's im2col matrix gives (GemmSharedA's
  // multiply, or multiply_onto with the bias, weights packed once: the sum fits one block),
  // bit for bit, computed straight from the image; false, with nothing written, where the
  // level has no such kernel or the shape is not one it covers
  bool (*conv_tile)(const ConvTile& t);
  // a tiny or vector-shaped product, whole (Eigen's coefficient-wise or GEMV expression)
  void (*small)(const GemmProduct& p);
  // Eigen 3.4's one-thread blocking heuristic at `caches` (gemm.hpp's reference_blocking)
  void (*blocking)(std::int64_t& k, std::int64_t& m, std::int64_t& n, const CacheSizes& caches);
  // for tests: Eigen's own computeProductBlockingSizes with its cache sizes set to `caches`
  void (*eigen_blocking)(const CacheSizes& caches, std::int64_t& k, std::int64_t& m,
                         std::int64_t& n);
  // tells this level's Eigen the cache sizes, as a CPU would report them (tests, emulation)
  void (*set_eigen_caches)(const CacheSizes& caches);
};

// the levels a build may compile (CMake's _ropes_kernel_levels; gemm.cpp sees the compiled ones
// as ROPES_NN_KERNEL_V4, ROPES_NN_KERNEL_V3 and ROPES_NN_KERNEL_BASELINE)
namespace kernel_v4 {
extern const GemmKernels kGemm;
}
namespace kernel_v3 {
extern const GemmKernels kGemm;
}
namespace kernel_baseline {
extern const GemmKernels kGemm;
}
namespace kernel_native {
extern const GemmKernels kGemm;
}

}  // namespace ropes::nn
