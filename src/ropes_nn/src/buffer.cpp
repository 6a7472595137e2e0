#include "ropes_nn/buffer.hpp"

#include <cstdlib>
#include <map>
#include <mutex>
#include <utility>
#include <vector>

namespace ropes::nn::pool {

namespace {

constexpr std::size_t kAlignment = 64;

// blocks are kept per exact byte size: a training step asks for the same sizes each time.
// One list per size that only grows, so that recycling a block allocates nothing once the
// list has seen as many blocks of its size (what makes a warm inference call malloc-free).
struct Pool {
  std::mutex mutex;
  std::map<std::size_t, std::vector<void*>> free_blocks;
  std::size_t cached = 0;
  std::size_t max_cached = [] {
    if (const char* env = std::getenv("ROPES_POOL_MAX_BYTES")) {
      return static_cast<std::size_t>(std::strtoull(env, nullptr, 10));
    }
    return std::size_t{4} << 30;
  }();

  ~Pool() {
    for (auto& [bytes, blocks] : free_blocks)
      for (void* p : blocks)
        std::free(p);
  }
};

Pool& instance() {
  static Pool* pool = new Pool;  // never destroyed: tensors may outlive static destructors
  return *pool;
}

std::size_t rounded(std::size_t bytes) {
  return (std::max<std::size_t>(bytes, 1) + kAlignment - 1) / kAlignment * kAlignment;
}

}  // namespace

void* allocate(std::size_t bytes) {
  const std::size_t size = rounded(bytes);
  Pool& pool = instance();
  {
    std::lock_guard<std::mutex> lock(pool.mutex);
    const auto it = pool.free_blocks.find(size);
    if (it != pool.free_blocks.end() && !it->second.empty()) {
      void* p = it->second.back();
      it->second.pop_back();
      pool.cached -= size;
      return p;
    }
  }
  void* p = std::aligned_alloc(kAlignment, size);
  if (!p) {
    // give the cache back and try once more before failing
    release_cached();
    p = std::aligned_alloc(kAlignment, size);
    if (!p)
      throw std::bad_alloc();
  }
  return p;
}

void deallocate(void* p, std::size_t bytes) noexcept {
  if (!p)
    return;
  const std::size_t size = rounded(bytes);
  Pool& pool = instance();
  {
    std::lock_guard<std::mutex> lock(pool.mutex);
    if (pool.cached + size <= pool.max_cached) {
      try {
        pool.free_blocks[size].push_back(p);
        pool.cached += size;
        return;
      } catch (const std::bad_alloc&) {
        // no room for the list entry: give the block back to the system instead
      }
    }
  }
  std::free(p);
}

std::size_t cached_bytes() {
  Pool& pool = instance();
  std::lock_guard<std::mutex> lock(pool.mutex);
  return pool.cached;
}

void release_cached() {
  Pool& pool = instance();
  std::map<std::size_t, std::vector<void*>> blocks;
  {
    std::lock_guard<std::mutex> lock(pool.mutex);
    blocks.swap(pool.free_blocks);
    pool.cached = 0;
  }
  for (auto& [bytes, list] : blocks)
    for (void* p : list)
      std::free(p);
}

}  // namespace ropes::nn::pool
