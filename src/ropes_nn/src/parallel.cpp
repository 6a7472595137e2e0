#include "ropes_nn/parallel.hpp"

#include <omp.h>
#include <Eigen/Core>

#include <algorithm>
#include <atomic>
#include <cstdlib>
#include <exception>
#include <mutex>
#include <stdexcept>
#include <string>
#include <thread>

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

// serialises the writes of Eigen's own (plain int) thread setting
std::mutex g_eigen_mutex;

std::atomic<int>& thread_setting() {
  static std::atomic<int> threads{[] {
    const int n = default_threads();
    const std::lock_guard<std::mutex> lock(g_eigen_mutex);
    Eigen::setNbThreads(n);
    return n;
  }()};
  return threads;
}
}  // namespace

void set_num_threads(int n) {
  if (n < 1) {
    throw std::invalid_argument("set_num_threads: " + std::to_string(n) + "; expected >= 1");
  }
  std::atomic<int>& setting = thread_setting();
  const std::lock_guard<std::mutex> lock(g_eigen_mutex);
  setting.store(n);
  Eigen::setNbThreads(n);
}

int num_threads() {
  return thread_setting().load();
}

int parallel_chunks(std::int64_t n) {
  return static_cast<int>(std::max<std::int64_t>(1, std::min<std::int64_t>(num_threads(), n)));
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
