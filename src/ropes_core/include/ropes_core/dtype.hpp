#pragma once
/// @file dtype.hpp
/// The element types of the workspace's tensor files (.npy, .safetensors, datasets).
#include <cstddef>
#include <cstdint>
#include <vector>

namespace ropes::core {

/// Element types of tensor files.
enum class DType { kU8, kI32, kI64, kF32, kF64 };

/// Bytes per element of `dtype`.
std::size_t dtype_size(DType dtype);
/// "u8", "i32", "i64", "f32" or "f64".
const char* dtype_name(DType dtype);
/// Bytes of an array of `dtype` and `shape` into `bytes`; false (and `bytes` untouched) for
/// a negative dimension or a count that overflows 64 bits. Both file readers bound their
/// allocations with it.
bool checked_byte_count(DType dtype, const std::vector<std::int64_t>& shape, std::uint64_t* bytes);

}  // namespace ropes::core
