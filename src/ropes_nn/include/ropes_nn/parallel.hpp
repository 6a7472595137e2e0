#pragma once
/// @file parallel.hpp
/// Threads of ropes_nn's kernels (OpenMP underneath).
///
/// Determinism: a kernel's result has the same bits at every thread count. Work is split into
/// contiguous chunks of fixed bounds; a sum over a batch keeps one partial sum per reduction
/// block, whose bounds depend on the batch size alone (for_each_reduction_block), and adds the
/// blocks in order; matrix products split their rows in whole register panels, or their
/// columns in whole blocks of Eigen's loop (src/gemm.hpp), and never use Eigen's own threads. The
/// thread count only decides which thread computes which block.

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

/// Sets the thread count (>= 1). Default: the ROPES_NUM_THREADS environment
/// variable if set, else the number of hardware threads. Throws std::invalid_argument for
/// n < 1. Safe to call while other threads run kernels: they see the old or the new count
/// (an atomic), never a torn value, and a kernel that has sized its per-chunk buffers keeps
/// its own chunk count (see parallel_chunks).
void set_num_threads(int n);
int num_threads();

/// Pins the cache sizes Eigen blocks its matrix products with, process-wide, to the
/// workspace's reference (those of the Zen 5 machine the tables were measured on: 48 KiB L1,
/// 1 MiB L2). Eigen otherwise queries them from the CPU, and the blocking decides in how many
/// runs a long sum is split: a product outside the kernels (ropes_eval's PCA and
/// calibrations) would then differ in its last bits from one CPU to another. ropes_nn's own
/// products do not read the setting (src/gemm.hpp). Idempotent and thread-safe; the first
/// use of num_threads or set_num_threads calls it. It changes only how fast another Eigen
/// product of the process runs, never its value beyond rounding.
///
/// For tests: with ROPES_EMULATE_CPU_CACHES="l1,l2,l3" (bytes) set, Eigen is first told those
/// sizes, as another CPU would report them, and then pinned: a run under it must give the
/// same bits as without.
void pin_eigen_blocking();

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

/// The most blocks a reduction over n items is split into: up to this many threads share it.
constexpr std::int64_t kReductionBlocks = 16;

/// The number of blocks a reduction over n items keeps partial sums for: min(n, 16), at
/// least 1. It depends on n alone, so the sum has the same bits at every thread count.
int reduction_blocks(std::int64_t n);

/// Calls body(block, begin, end) for block = 0 .. reduction_blocks(n) - 1 (block b covers
/// [n b / blocks, n (b + 1) / blocks)), the blocks spread over the threads. The caller keeps
/// one partial sum per block and adds them in block order.
template <typename F>
void for_each_reduction_block(std::int64_t n, const F& body) {
  if (n <= 0)
    return;
  const int blocks = reduction_blocks(n);
  parallel_for(blocks, [&](int, std::int64_t first, std::int64_t last) {
    for (std::int64_t b = first; b < last; ++b)
      body(static_cast<int>(b), n * b / blocks, n * (b + 1) / blocks);
  });
}

}  // namespace ropes::nn
