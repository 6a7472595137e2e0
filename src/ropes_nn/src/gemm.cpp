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

void rows_of_product(GemmProduct p, std::int64_t begin, std::int64_t end) {
  thread_local Buffer block_a, block_b;
  p.block_a = at_least(block_a, static_cast<std::size_t>(p.kc * p.mc));
  p.block_b = at_least(block_b, static_cast<std::size_t>(p.kc * p.nc));
  gemm_kernels().rows(p, begin, end);
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

void gemm(const float* a, bool a_transposed, const float* b, bool b_transposed, float* c,
          std::int64_t m, std::int64_t k, std::int64_t n, bool accumulate) {
  if (m == 0 || n == 0)
    return;
  if (k == 0) {
    if (!accumulate)
      std::fill(c, c + m * n, 0.0f);
    return;
  }
  GemmProduct p{a, a_transposed, b,      b_transposed, c, m, k, n, accumulate, k, n,
                m, nullptr,      nullptr};
  if (m == 1 || n == 1 || k + m + n < kCoefficientBased) {
    gemm_kernels().small(p);
    return;
  }
  // a row-major product is Eigen's column-major one transposed: mc runs over n, nc over m
  reference_blocking(p.kc, p.mc, p.nc);
  const std::int64_t quanta = (m + kRowQuantum - 1) / kRowQuantum;
  const double work = static_cast<double>(m) * static_cast<double>(n) * static_cast<double>(k);
  std::int64_t chunks = 1;
  if (!omp_in_parallel()) {
    chunks = std::min<std::int64_t>(
        {num_threads(), quanta,
         std::max<std::int64_t>(1, static_cast<std::int64_t>(work / kMinWorkPerThread))});
  }
  if (chunks == 1) {
    rows_of_product(p, 0, m);
    return;
  }
  parallel_for(quanta, static_cast<int>(chunks), [&](int, std::int64_t begin, std::int64_t end) {
    rows_of_product(p, begin * kRowQuantum, std::min(end * kRowQuantum, m));
  });
}

}  // namespace ropes::nn
