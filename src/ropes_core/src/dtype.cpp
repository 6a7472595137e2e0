#include "ropes_core/dtype.hpp"

#include <limits>

namespace ropes::core {

std::size_t dtype_size(DType dtype) {
  switch (dtype) {
    case DType::kU8:
      return 1;
    case DType::kI32:
    case DType::kF32:
      return 4;
    case DType::kI64:
    case DType::kF64:
      return 8;
  }
  return 0;
}

const char* dtype_name(DType dtype) {
  switch (dtype) {
    case DType::kU8:
      return "u8";
    case DType::kI32:
      return "i32";
    case DType::kI64:
      return "i64";
    case DType::kF32:
      return "f32";
    case DType::kF64:
      return "f64";
  }
  return "?";
}

bool checked_byte_count(DType dtype, const std::vector<std::int64_t>& shape, std::uint64_t* bytes) {
  std::uint64_t count = dtype_size(dtype);
  for (std::int64_t d : shape) {
    if (d < 0)
      return false;
    if (d != 0 &&
        count > std::numeric_limits<std::uint64_t>::max() / static_cast<std::uint64_t>(d)) {
      return false;
    }
    count *= static_cast<std::uint64_t>(d);
  }
  *bytes = count;
  return true;
}

}  // namespace ropes::core
