#pragma once
// Test helpers shared by the ropes_nn tests: NpyArrays from typed values and back.

#include <cstdint>
#include <cstring>
#include <vector>

#include "ropes_nn/npy.hpp"

namespace ropes::nn::test {

// an array of `dtype` and `shape` holding `v` (T must be the dtype's C type)
template <typename T>
NpyArray make_array(DType dtype, std::vector<std::int64_t> shape, const std::vector<T>& v) {
  NpyArray a;
  a.dtype = dtype;
  a.shape = std::move(shape);
  a.data.resize(v.size() * sizeof(T));
  if (!v.empty())
    std::memcpy(a.data.data(), v.data(), a.data.size());
  return a;
}

// the array's elements as T
template <typename T>
std::vector<T> values(const NpyArray& a) {
  std::vector<T> v(a.data.size() / sizeof(T));
  if (!v.empty())
    std::memcpy(v.data(), a.data.data(), a.data.size());
  return v;
}

}  // namespace ropes::nn::test
