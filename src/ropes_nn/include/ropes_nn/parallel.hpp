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

namespace ropes::nn {

namespace detail {
/// What parallel_for hands its implementation: a non-owning reference to the caller's
/// callable, so that running a lambda allocates nothing (a std::function may). Built only
/// inside parallel_for's own call, where the callable outlives it.
class ChunkBody {
 public:
  template <typename F>
  explicit ChunkBody(const F& f)
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
void parallel_for_chunks(std::int64_t n, int chunks, ChunkBody body);
}  // namespace detail

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
/// The region always has num_threads() threads (surplus ones idle), so that OpenMP reuses
/// one thread team for every call and a warm call allocates nothing.
template <typename F>
void parallel_for(std::int64_t n, int chunks, const F& body) {
  detail::parallel_for_chunks(n, chunks, detail::ChunkBody(body));
}

/// parallel_for(n, parallel_chunks(n), body).
template <typename F>
void parallel_for(std::int64_t n, const F& body) {
  if (n > 0)
    detail::parallel_for_chunks(n, parallel_chunks(n), detail::ChunkBody(body));
}

}  // namespace ropes::nn
