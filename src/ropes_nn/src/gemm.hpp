#pragma once
// Private: the matrix products of ropes_nn's kernels, without heap allocation, with the same
// bits on every CPU of an instruction-set level and at every thread count.
#include <cstdint>

#include "gemm_kernel.hpp"

namespace ropes::nn {

// c [m, n] = op(a) [m, k] * op(b) [k, n], or c += when `accumulate`. All three are row-major
// and contiguous; op(a) is a, stored [m, k], or the transpose of a stored [k, m] when
// `a_transposed` (the same for b: [k, n], or [n, k] transposed).
//
// The arithmetic is Eigen's general_matrix_matrix_product (its packing and register
// kernel), with two things fixed by the workspace instead of by the machine:
// - the blocking (kc, mc, nc): Eigen evaluates its heuristic at the cache sizes it queries
//   from the CPU, and kc decides in how many runs the sum over k is split, mc which
//   register panel (and so which order of operations) each output takes. Here the same
//   heuristic runs at fixed reference sizes (reference_blocking below).
// - the threads: outside a parallel region the rows of op(a) are split over the threads in
//   multiples of 16 (whole register panels), or its columns in multiples of mc (whole
//   blocks of Eigen's loop) when the rows are too few, with the blocking of the whole
//   product, so each output element is computed by the same instructions at every thread
//   count.
// Eigen's own threading is never used (set_num_threads keeps Eigen at one thread).
// The instruction set: the Eigen half (gemm_kernel.cpp) is compiled for x86-64-v4 and v3
// (and the baseline's flags when the baseline is below v3); gemm_kernels() picks the highest
// the CPU has, or the one ROPES_ISA names. Each level gives the same bits on every CPU that
// runs it; two levels differ (another vector width orders the sums otherwise).
// Small and vector-shaped products go to Eigen's coefficient-wise and GEMV expressions,
// which depend on neither. The packing blocks come from a per-thread workspace that only
// grows, so a warm inference does not allocate.
void gemm(const float* a, bool a_transposed, const float* b, bool b_transposed, float* c,
          std::int64_t m, std::int64_t k, std::int64_t n, bool accumulate);

inline void gemm(const float* a, const float* b, float* c, std::int64_t m, std::int64_t k,
                 std::int64_t n) {
  gemm(a, false, b, false, c, m, k, n, false);
}

// Whether gemm() runs an m x k x n product through the blocked kernel (else, tiny and
// vector-shaped products, through Eigen's coefficient-wise and GEMV expressions).
bool gemm_is_blocked(std::int64_t m, std::int64_t k, std::int64_t n);

// The blocking gemm() gives a blocked m x k x n product, in Eigen's column-major view of it:
// kc splits the sum over k, mc blocks the columns n, nc the rows m.
struct GemmBlocking {
  std::int64_t kc, mc, nc;
};
GemmBlocking gemm_blocking(std::int64_t m, std::int64_t k, std::int64_t n);

// One tile of a blocked product, on the calling thread, blocked as the `whole` product is:
// c [m, n] (+)= op(a) [m, k] * op(b) [k, n], with lda, ldb and ldc the row strides of a, b
// and c as stored. A tile of columns [c0, c0 + n) of the whole, c0 a multiple of whole.mc and
// n whole.mc (or what is left), gets the bits of those columns of gemm(); so does a tile of
// the sum over k, [k0, k0 + k), k0 a multiple of whole.kc and k whole.kc (or what is left),
// accumulated onto the tiles before it in order. The convolutions (conv.cpp) build their
// im2col matrices a tile at a time this way, in cache.
void gemm_tile(const GemmBlocking& whole, const float* a, bool a_transposed, std::int64_t lda,
               const float* b, bool b_transposed, std::int64_t ldb, float* c, std::int64_t ldc,
               std::int64_t m, std::int64_t k, std::int64_t n, bool accumulate);

// Several products with one op(a) (a convolution's weights, each image or tile its own b and
// c): op(a) is packed once, on the calling thread, when its sum fits one block of the whole
// product's blocking (k <= kc); each multiply() then gets the bits gemm_tile gives (and is
// gemm_tile where it does not fit). One at a time on a thread; not copyable.
class GemmSharedA {
 public:
  GemmSharedA(const GemmBlocking& whole, const float* a, bool a_transposed, std::int64_t lda,
              std::int64_t m, std::int64_t k);
  GemmSharedA(const GemmSharedA&) = delete;
  GemmSharedA& operator=(const GemmSharedA&) = delete;
  // c [m, n] (+)= op(a) * b [k, n], b not transposed, row strides ldb and ldc
  void multiply(const float* b, std::int64_t ldb, float* c, std::int64_t ldc, std::int64_t n,
                bool accumulate);
  // c [m, n] = op(a) * b + start[r] on each row r: the bits of the product followed by
  // adding start[r] to each element of row r (the sum over k is one block: every element is
  // one accumulated sum added to what c holds, so starting from start[r] instead of 0 is the
  // same addition)
  void multiply_onto(const float* start, const float* b, std::int64_t ldb, float* c,
                     std::int64_t ldc, std::int64_t n);
  // whether op(a) was packed once (its sum fits one block of the whole product)
  bool packed() const { return packed_ != nullptr; }

 private:
  GemmBlocking whole_;
  const float* a_;
  bool a_transposed_;
  std::int64_t lda_, m_, k_;
  float* packed_ = nullptr;  // this thread's packed op(a), or null where it did not fit
};

// The level's direct kernel for one tile of a stride-1 convolution's forward product
// (gemm_kernel.hpp's conv_tile): the bits GemmSharedA's product of the tile's im2col matrix
// gives, with the weights packed once (their sum fits one block), without building that
// matrix; false, nothing written, where the level or the shape has none.
bool gemm_conv_tile(const ConvTile& tile);
// Whether gemm_conv_tile takes this tile's shape (reads none of its data).
bool gemm_conv_tile_covers(const ConvTile& tile);

// The blocking reference: the cache sizes Eigen 3.4 queries on the AMD Zen 5 machine the
// workspace's tables were measured on (L1d 48 KiB, L2 1 MiB; L3 only needs to be non-zero).
constexpr CacheSizes kReferenceCaches{49152, 1048576, 532676608};

// Eigen 3.4's one-thread blocking heuristic (evaluateProductBlockingSizesHeuristic, for
// float, KcFactor 1) evaluated at `caches` instead of the CPU's, for the selected kernels: on entry
// k, m, n are the product's depth, rows and columns of Eigen's column-major view; on return kc, mc,
// nc.
void reference_blocking(std::int64_t& k, std::int64_t& m, std::int64_t& n,
                        const CacheSizes& caches = kReferenceCaches);

// The kernels this process runs: the highest level the CPU has among those compiled, or the
// one ROPES_ISA names (v4, v3, or baseline; an unknown name or a level the CPU lacks throws
// with the names this build has). Chosen once, at the first call.
const GemmKernels& gemm_kernels();

// For tests: what Eigen's own heuristic (computeProductBlockingSizes, one thread) gives with
// its cache sizes set to `caches`, compiled as the kernels are. It sets Eigen's process-wide
// cache sizes, computes and restores them: not for use while other threads run products.
void eigen_blocking_at(const CacheSizes& caches, std::int64_t& k, std::int64_t& m, std::int64_t& n);

}  // namespace ropes::nn
