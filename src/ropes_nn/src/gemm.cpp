#include "gemm.hpp"

#include <omp.h>

#include <algorithm>
#include <cstdlib>
#include <mutex>
#include <stdexcept>
#include <string>

#include "gemm_kernel.hpp"
#include "ropes_nn/buffer.hpp"
#include "ropes_nn/build_info.hpp"
#include "ropes_nn/parallel.hpp"

namespace ropes::nn {

namespace {

// the kernels compiled into this build, highest level first (CMake defines one macro per
// level it compiled: ROPES_NN_KERNEL_V4, ROPES_NN_KERNEL_V3, ROPES_NN_KERNEL_BASELINE)
struct Compiled {
  const char* name;  // what ROPES_ISA names it
  const GemmKernels* kernels;
};
const Compiled kCompiled[] = {
#ifdef ROPES_NN_KERNEL_V4
    {"v4", &kernel_v4::kGemm},
#endif
#ifdef ROPES_NN_KERNEL_V3
    {"v3", &kernel_v3::kGemm},
#endif
#ifdef ROPES_NN_KERNEL_BASELINE
#ifdef ROPES_NN_KERNEL_BASELINE_NAME
    {ROPES_NN_KERNEL_BASELINE_NAME, &kernel_native::kGemm},
#else
    {"baseline", &kernel_baseline::kGemm},
#endif
#endif
};

bool cpu_has(const char* level) {
  if (std::string(level).rfind("x86-64", 0) != 0)
    return true;  // the baseline's own level, off x86-64: what the build targets
  const std::string wanted(level);
  for (const std::string& l : cpu_levels())
    if (wanted.rfind(l, 0) == 0 && (wanted.size() == l.size() || wanted[l.size()] == ' '))
      return true;
  return false;
}

const GemmKernels& select_kernels() {
  std::string names;
  for (const Compiled& c : kCompiled)
    names += (names.empty() ? "" : ", ") + std::string(c.name);
  if (const char* forced = std::getenv("ROPES_ISA"); forced != nullptr && *forced != '\0') {
    for (const Compiled& c : kCompiled) {
      if (c.name != std::string(forced))
        continue;
      if (!cpu_has(c.kernels->level))
        throw std::runtime_error(std::string("ROPES_ISA=") + forced + ": this CPU lacks " +
                                 c.kernels->level + "; unset ROPES_ISA or choose a lower level");
      return *c.kernels;
    }
    throw std::invalid_argument(std::string("ROPES_ISA=") + forced +
                                ": not a level of this build; expected one of " + names);
  }
  for (const Compiled& c : kCompiled)
    if (cpu_has(c.kernels->level))
      return *c.kernels;
  throw std::runtime_error(std::string("ropes_nn: this CPU has none of the kernels' levels (") +
                           names + ")");
}

// Eigen's own dispatch for tiny and vector-shaped products: coefficient-wise below this sum
// of the three sizes (EIGEN_GEMM_TO_COEFFBASED_THRESHOLD), GEMV for one row or column
constexpr std::int64_t kCoefficientBased = 20;
// rows go to threads in whole multiples of this (a multiple of every register panel width
// of Eigen's kernel), so that a row's arithmetic does not depend on the split
constexpr std::int64_t kRowQuantum = 16;
// Eigen's own threshold: no thread for less than this many multiply-adds
constexpr double kMinWorkPerThread = 50000;

// this thread's packing blocks, which only grow
float* at_least(Buffer& buffer, std::size_t size) {
  if (buffer.size() < size)
    buffer = Buffer(size);
  return buffer.data();
}

void block_of_product(GemmProduct p, std::int64_t r0, std::int64_t r1, std::int64_t c0,
                      std::int64_t c1) {
  thread_local Buffer block_a, block_b;
  p.block_a = at_least(block_a, static_cast<std::size_t>(p.kc * p.mc));
  p.block_b = at_least(block_b, static_cast<std::size_t>(p.kc * p.nc));
  gemm_kernels().block(p, r0, r1, c0, c1);
}

}  // namespace

const GemmKernels& gemm_kernels() {
  static const GemmKernels& selected = select_kernels();
  return selected;
}

void reference_blocking(std::int64_t& k, std::int64_t& m, std::int64_t& n,
                        const CacheSizes& caches) {
  gemm_kernels().blocking(k, m, n, caches);
}

void eigen_blocking_at(const CacheSizes& caches, std::int64_t& k, std::int64_t& m,
                       std::int64_t& n) {
  gemm_kernels().eigen_blocking(caches, k, m, n);
}

bool gemm_is_blocked(std::int64_t m, std::int64_t k, std::int64_t n) {
  return m > 1 && n > 1 && k > 0 && k + m + n >= kCoefficientBased;
}

GemmBlocking gemm_blocking(std::int64_t m, std::int64_t k, std::int64_t n) {
  // a row-major product is Eigen's column-major one transposed: mc runs over n, nc over m
  GemmBlocking b{k, n, m};
  reference_blocking(b.kc, b.mc, b.nc);
  return b;
}

void gemm_tile(const GemmBlocking& whole, const float* a, bool a_transposed, std::int64_t lda,
               const float* b, bool b_transposed, std::int64_t ldb, float* c, std::int64_t ldc,
               std::int64_t m, std::int64_t k, std::int64_t n, bool accumulate) {
  if (m == 0 || n == 0)
    return;
  const GemmProduct p{a,   a_transposed, b,        b_transposed, c,        m,   k,
                      n,   accumulate,   whole.kc, whole.mc,     whole.nc, lda, ldb,
                      ldc, nullptr,      nullptr};
  block_of_product(p, 0, m, 0, n);
}

void GemmSharedA::multiply_onto(const float* start, const float* b, std::int64_t ldb, float* c,
                                std::int64_t ldc, std::int64_t n) {
  if (packed_ == nullptr) {
    // a sum over several k blocks: the product, then the addition
    multiply(b, ldb, c, ldc, n, false);
    for (std::int64_t r = 0; r < m_; ++r)
      for (std::int64_t j = 0; j < n; ++j)
        c[r * ldc + j] = c[r * ldc + j] + start[r];
    return;
  }
  for (std::int64_t r = 0; r < m_; ++r)
    std::fill(c + r * ldc, c + r * ldc + n, start[r]);
  multiply(b, ldb, c, ldc, n, true);
}

GemmSharedA::GemmSharedA(const GemmBlocking& whole, const float* a, bool a_transposed,
                         std::int64_t lda, std::int64_t m, std::int64_t k)
    : whole_(whole), a_(a), a_transposed_(a_transposed), lda_(lda), m_(m), k_(k) {
  thread_local Buffer packed;
  GemmProduct p{a,        a_transposed, nullptr,  false, nullptr, m, k,       0,      false,
                whole.kc, whole.mc,     whole.nc, lda,   0,       0, nullptr, nullptr};
  // only weights whose sum fits one block are packed (and grow the buffer)
  if (m <= 0 || k <= 0 || k > whole.kc)
    return;
  p.block_b = at_least(packed, static_cast<std::size_t>(k * m));
  if (gemm_kernels().pack_a(p))
    packed_ = p.block_b;
}

bool gemm_conv_tile(const ConvTile& tile) {
  return gemm_kernels().conv_tile(tile);
}

bool gemm_conv_tile_covers(const ConvTile& tile) {
  return gemm_kernels().conv_tile_covers(tile);
}

void GemmSharedA::multiply(const float* b, std::int64_t ldb, float* c, std::int64_t ldc,
                           std::int64_t n, bool accumulate) {
  if (packed_ == nullptr) {
    gemm_tile(whole_, a_, a_transposed_, lda_, b, false, ldb, c, ldc, m_, k_, n, accumulate);
    return;
  }
  if (n == 0)
    return;
  thread_local Buffer block_a;
  const GemmProduct p{
      a_,         a_transposed_,
      b,          false,
      c,          m_,
      k_,         n,
      accumulate, whole_.kc,
      whole_.mc,  whole_.nc,
      lda_,       ldb,
      ldc,        at_least(block_a, static_cast<std::size_t>(whole_.kc * whole_.mc)),
      packed_};
  gemm_kernels().with_packed_a(p);
}

void gemm(const float* a, bool a_transposed, const float* b, bool b_transposed, float* c,
          std::int64_t m, std::int64_t k, std::int64_t n, bool accumulate) {
  if (m == 0 || n == 0)
    return;
  if (k == 0) {
    if (!accumulate)
      std::fill(c, c + m * n, 0.0f);
    return;
  }
  if (!gemm_is_blocked(m, k, n)) {
    const GemmProduct p{a,
                        a_transposed,
                        b,
                        b_transposed,
                        c,
                        m,
                        k,
                        n,
                        accumulate,
                        k,
                        n,
                        m,
                        a_transposed ? m : k,
                        b_transposed ? k : n,
                        n,
                        nullptr,
                        nullptr};
    gemm_kernels().small(p);
    return;
  }
  const GemmBlocking blocking = gemm_blocking(m, k, n);
  const GemmProduct p{a,
                      a_transposed,
                      b,
                      b_transposed,
                      c,
                      m,
                      k,
                      n,
                      accumulate,
                      blocking.kc,
                      blocking.mc,
                      blocking.nc,
                      a_transposed ? m : k,
                      b_transposed ? k : n,
                      n,
                      nullptr,
                      nullptr};
  // Two splits over threads, each leaving every element's instructions as in the whole
  // product: rows of op(a) in multiples of kRowQuantum, or, when the rows are too few for the
  // threads (a convolution's output channels for one image), columns in multiples of mc
  // (Eigen runs over its rows, our columns, in blocks of mc from the first: a run of whole
  // blocks is blocked the same way on its own)
  const double work = static_cast<double>(m) * static_cast<double>(n) * static_cast<double>(k);
  const std::int64_t most =
      omp_in_parallel()
          ? 1
          : std::min<std::int64_t>(
                num_threads(),
                std::max<std::int64_t>(1, static_cast<std::int64_t>(work / kMinWorkPerThread)));
  const std::int64_t row_quanta = (m + kRowQuantum - 1) / kRowQuantum;
  const std::int64_t col_quanta = (n + p.mc - 1) / p.mc;
  const std::int64_t row_chunks = std::min(most, row_quanta);
  const std::int64_t col_chunks = std::min(most, col_quanta);
  if (row_chunks >= col_chunks) {
    if (row_chunks == 1) {
      block_of_product(p, 0, m, 0, n);
      return;
    }
    parallel_for(row_quanta, static_cast<int>(row_chunks),
                 [&](int, std::int64_t begin, std::int64_t end) {
                   block_of_product(p, begin * kRowQuantum, std::min(end * kRowQuantum, m), 0, n);
                 });
    return;
  }
  parallel_for(col_quanta, static_cast<int>(col_chunks),
               [&](int, std::int64_t begin, std::int64_t end) {
                 block_of_product(p, 0, m, begin * p.mc, std::min(end * p.mc, n));
               });
}

}  // namespace ropes::nn
