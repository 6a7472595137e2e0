#pragma once
/// @file parallel.hpp
/// Threads of ropes_nn's kernels (OpenMP underneath).
///
/// Determinism: work is split into num_threads() contiguous chunks of fixed bounds, and
/// partial sums are combined in chunk order, so results are bit-identical run to run for
/// the same thread count. Across thread counts, sums that are split (the weight gradient of a
/// convolution over the batch; Eigen's matrix products) are added in another order: results
/// agree to float rounding (relative differences of order 1e-6 per reduction), not bitwise.

#include <cstdint>
#include <functional>

namespace ropes::nn {

/// Sets the thread count (>= 1); also Eigen's. Default: the ROPES_NUM_THREADS environment
/// variable if set, else the number of hardware threads. Throws std::invalid_argument for n < 1.
void set_num_threads(int n);
int num_threads();

/// Calls body(chunk, begin, end) for num_threads() (or fewer, if n is smaller) contiguous
/// chunks covering [0, n), in parallel. Chunk bounds depend only on n and the thread count.
void parallel_for(std::int64_t n,
                  const std::function<void(int chunk, std::int64_t begin, std::int64_t end)>& body);

}  // namespace ropes::nn
