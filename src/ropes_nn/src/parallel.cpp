#include "ropes_nn/parallel.hpp"

#include <omp.h>
#include <Eigen/Core>

#include <algorithm>
#include <atomic>
#include <cstdio>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>

#include "gemm.hpp"
#include "ropes_nn/demand.hpp"

namespace ropes::nn {

namespace {
int default_threads() {
  if (const char* env = std::getenv("ROPES_NUM_THREADS")) {
    const int n = std::atoi(env);
    if (n >= 1)
      return n;
  }
  return std::max(1u, std::thread::hardware_concurrency());
}

std::atomic<int>& thread_setting() {
  static std::atomic<int> threads{[] {
    // the kernels' level, chosen now so that a bad ROPES_ISA is refused before any work
    gemm_kernels();
    pin_eigen_blocking();
    // Eigen never threads a product of ropes_nn's (its parallel GEMM blocks and splits the
    // work by the thread count); the kernels split work themselves (src/gemm.hpp)
    Eigen::setNbThreads(1);
    return default_threads();
  }()};
  return threads;
}
}  // namespace

void pin_eigen_blocking() {
  static const bool pinned = [] {
    if (const char* emulate = std::getenv("ROPES_EMULATE_CPU_CACHES")) {
      long long l1 = 0, l2 = 0, l3 = 0;
      char tail = 0;
      if (std::sscanf(emulate, "%lld,%lld,%lld%c", &l1, &l2, &l3, &tail) != 3 || l1 <= 0 ||
          l2 <= 0 || l3 < 0) {
        throw std::invalid_argument(std::string("ROPES_EMULATE_CPU_CACHES: \"") + emulate +
                                    "\"; expected three byte counts \"l1,l2,l3\", l1 and l2 > 0");
      }
      Eigen::setCpuCacheSizes(l1, l2, l3);
      gemm_kernels().set_eigen_caches({l1, l2, l3});
    }
    Eigen::setCpuCacheSizes(kReferenceCaches.l1, kReferenceCaches.l2, kReferenceCaches.l3);
    return true;
  }();
  (void)pinned;
}

void set_num_threads(int n) {
  if (n < 1) {
    throw std::invalid_argument("set_num_threads: " + std::to_string(n) + "; expected >= 1");
  }
  thread_setting().store(n);
}

int num_threads() {
  return thread_setting().load();
}

int parallel_chunks(std::int64_t n) {
  return static_cast<int>(std::max<std::int64_t>(1, std::min<std::int64_t>(num_threads(), n)));
}

int reduction_blocks(std::int64_t n) {
  return static_cast<int>(std::max<std::int64_t>(1, std::min(kReductionBlocks, n)));
}

void detail::parallel_for_chunks(std::int64_t n, int chunks, ChunkBody body) {
  if (n <= 0)
    return;
  ROPES_DEMAND(chunks >= 1 && chunks <= n, "parallel_for: " + std::to_string(chunks) +
                                               " chunks for " + std::to_string(n) +
                                               " items; expected 1..n");
  if (chunks == 1) {
    body(0, 0, n);
    return;
  }
  // a team of the same size every time: libgomp builds a new team (and allocates) whenever
  // the size changes, and the chunk count varies from kernel to kernel
  const int team = std::max(2, num_threads());
  // an exception may not leave an OpenMP region: keep the first, rethrow it after
  std::exception_ptr failure;
#pragma omp parallel for num_threads(team) schedule(static, 1)
  for (int c = 0; c < chunks; ++c) {
    try {
      body(c, n * c / chunks, n * (c + 1) / chunks);
    } catch (...) {
#pragma omp critical(ropes_parallel_for_failure)
      if (!failure)
        failure = std::current_exception();
    }
  }
  if (failure)
    std::rethrow_exception(failure);
}

}  // namespace ropes::nn
