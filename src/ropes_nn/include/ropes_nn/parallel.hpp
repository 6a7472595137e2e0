#pragma once
/// @file parallel.hpp
/// Threads of ropes_nn's kernels (OpenMP underneath).
///
/// Determinism: work is split into num_threads() contiguous chunks of fixed bounds, and
/// partial sums are combined in chunk order, so results are bit-identical run to run for
/// the same thread count. Across thread counts, sums that are split (the weight gradient of a
/// convolution over the batch; Eigen's matrix products in matmul and in the convolutions'
/// backward) are added in another order: results agree to float rounding (relative
/// differences of order 1e-6 per reduction), not bitwise. A convolution's forward gives the
/// same bits at every thread count.

#include <cstdint>
#include <type_traits>
#include <utility>

namespace ropes::nn {

/// What parallel_for runs: a non-owning reference to a callable
/// void(int chunk, std::int64_t begin, std::int64_t end), so that handing a lambda to
/// parallel_for allocates nothing (a std::function may). The callable must outlive the call,
/// which it does when it is passed directly, as in parallel_for(n, [&](...) { ... }).
class ChunkBody {
 public:
  template <typename F, typename = std::enable_if_t<!std::is_same_v<std::decay_t<F>, ChunkBody>>>
  ChunkBody(const F& f)  // NOLINT(google-explicit-constructor): lambdas convert implicitly
      : object_(static_cast<const void*>(&f)),
        call_([](const void* o, int chunk, std::int64_t begin, std::int64_t end) {
          (*static_cast<const F*>(o))(chunk, begin, end);
        }) {}
  void operator()(int chunk, std::int64_t begin, std::int64_t end) const {
    call_(object_, chunk, begin, end);
  }

 private:
  const void* object_;
  void (*call_)(const void*, int, std::int64_t, std::int64_t);
};

/// Sets the thread count (>= 1); also Eigen's. Default: the ROPES_NUM_THREADS environment
/// variable if set, else the number of hardware threads. Throws std::invalid_argument for
/// n < 1. Safe to call while other threads run kernels: they see the old or the new count
/// (an atomic), never a torn value, and a kernel that has sized its per-chunk buffers keeps
/// its own chunk count (see parallel_chunks).
void set_num_threads(int n);
int num_threads();

/// The number of chunks parallel_for(n, body) splits [0, n) into at the current thread
/// count: min(num_threads(), n), and at least 1. A kernel that keeps one partial buffer per
/// chunk reads this once, sizes its buffers with it and passes the same count to
/// parallel_for(n, chunks, body), so a concurrent set_num_threads cannot make a chunk index
/// run past the buffers.
int parallel_chunks(std::int64_t n);

/// Calls body(chunk, begin, end) for chunk = 0 .. chunks - 1, contiguous pieces covering
/// [0, n) (chunk c gets [n c / chunks, n (c + 1) / chunks)), in parallel. Bounds depend only
/// on n and chunks. n <= 0 does nothing. chunks must be in [1, n] (ROPES_DEMAND).
/// An exception thrown by a body reaches the caller (the first one, after every chunk ends).
void parallel_for(std::int64_t n, int chunks, ChunkBody body);

/// parallel_for(n, parallel_chunks(n), body).
void parallel_for(std::int64_t n, ChunkBody body);

}  // namespace ropes::nn
