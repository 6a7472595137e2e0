#include "ropes_nn/parallel.hpp"

#include <omp.h>
#include <Eigen/Core>

#include <algorithm>
#include <cstdlib>
#include <exception>
#include <stdexcept>
#include <string>
#include <thread>

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

int& thread_setting() {
  static int threads = [] {
    const int n = default_threads();
    Eigen::setNbThreads(n);
    return n;
  }();
  return threads;
}
}  // namespace

void set_num_threads(int n) {
  if (n < 1) {
    throw std::invalid_argument("set_num_threads: " + std::to_string(n) + "; expected >= 1");
  }
  thread_setting() = n;
  Eigen::setNbThreads(n);
}

int num_threads() {
  return thread_setting();
}

void parallel_for(std::int64_t n,
                  const std::function<void(int, std::int64_t, std::int64_t)>& body) {
  if (n <= 0)
    return;
  const int chunks = static_cast<int>(std::min<std::int64_t>(num_threads(), n));
  if (chunks == 1) {
    body(0, 0, n);
    return;
  }
  // an exception may not leave an OpenMP region: keep the first, rethrow it after
  std::exception_ptr failure;
#pragma omp parallel for num_threads(chunks) schedule(static, 1)
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
