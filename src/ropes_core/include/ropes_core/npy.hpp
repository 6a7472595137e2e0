#pragma once
/// @file npy.hpp
/// NumPy .npy files (format versions 1.0, 2.0 and 3.0): read and write little-endian,
/// C-order arrays of u8, i32, i64, f32 and f64, the types the workspace's datasets and
/// fixtures use. Anything else is refused with a message, never guessed at.

#include <cstddef>
#include <cstdint>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "ropes_core/dtype.hpp"
#include "ropes_core/file_format_error.hpp"

namespace ropes::core {

/// An n-dimensional array as stored in a file: element type, shape and the raw
/// little-endian bytes in C (row-major) order. data.size() == element_count() * itemsize.
struct NpyArray {
  DType dtype = DType::kF32;
  std::vector<std::int64_t> shape;  // empty shape: a scalar (one element)
  std::vector<std::uint8_t> data;

  /// Product of the shape (1 for a scalar).
  std::int64_t element_count() const;
};

/// An array of `dtype` and `shape` holding `values` in C order, copied. Throws
/// std::invalid_argument when sizeof(T) is not the dtype's size (T must be its C type: uint8_t,
/// int32_t, int64_t, float, double).
template <typename T>
NpyArray make_npy_array(DType dtype, std::vector<std::int64_t> shape,
                        const std::vector<T>& values) {
  if (sizeof(T) != dtype_size(dtype)) {
    throw std::invalid_argument(std::string("make_npy_array: elements of ") +
                                std::to_string(sizeof(T)) + " bytes for dtype " +
                                dtype_name(dtype) + "; expected its C type");
  }
  NpyArray a;
  a.dtype = dtype;
  a.shape = std::move(shape);
  a.data.resize(values.size() * sizeof(T));
  if (!values.empty())
    std::memcpy(a.data.data(), values.data(), a.data.size());
  return a;
}

/// The elements of `a` as T, copied. Throws std::invalid_argument when sizeof(T) is not the
/// size of a's dtype.
template <typename T>
std::vector<T> npy_values(const NpyArray& a) {
  if (sizeof(T) != dtype_size(a.dtype)) {
    throw std::invalid_argument(std::string("npy_values: elements of ") +
                                std::to_string(sizeof(T)) + " bytes from an array of " +
                                dtype_name(a.dtype) + "; expected its C type");
  }
  std::vector<T> v(a.data.size() / sizeof(T));
  if (!v.empty())
    std::memcpy(v.data(), a.data.data(), v.size() * sizeof(T));
  return v;
}

/// What a .npy header says, and where the data starts: enough to read rows of a large
/// file without loading it whole.
struct NpyHeader {
  DType dtype = DType::kF32;
  std::vector<std::int64_t> shape;
  std::uint64_t data_offset = 0;  // bytes from the start of the file
  std::uint64_t data_bytes = 0;   // element count * itemsize
};

/// Limits that keep a hostile file from making the reader allocate without bound.
inline constexpr std::size_t kNpyMaxHeaderBytes = 1 << 20;  // numpy writes < 1 KiB
inline constexpr int kNpyMaxRank = 32;                      // numpy's own limit

/// Parses the header at the start of `bytes` (`size` bytes available). `name` is used in
/// messages. Throws FileFormatError for a bad magic string, an unknown version, a header
/// longer than kNpyMaxHeaderBytes or than `size`, a malformed dictionary, an unsupported
/// descr (big-endian, other types), fortran_order True, a negative dimension or a byte
/// count that overflows 64 bits.
NpyHeader parse_npy_header(const std::uint8_t* bytes, std::size_t size, const std::string& name);

/// Reads the header of the file at `path`, and checks that the file holds exactly the
/// bytes the header promises.
NpyHeader read_npy_header(const std::filesystem::path& path);

/// Reads a whole .npy file. Throws FileFormatError as parse_npy_header does, and when the
/// file is shorter or longer than its header says.
NpyArray read_npy(const std::filesystem::path& path);

/// Parses a whole .npy image held in memory.
NpyArray parse_npy(const std::uint8_t* bytes, std::size_t size, const std::string& name);

/// The bytes of a version 1.0 .npy file holding `array` (version 2.0 if the header needs
/// more than 65535 bytes). Throws std::invalid_argument when data.size() does not match
/// the shape or a dimension is negative.
std::vector<std::uint8_t> serialize_npy(const NpyArray& array);

/// Writes `array` to `path` through a temporary file in the same directory and a rename,
/// so a reader never sees a half-written file. Throws FileFormatError when the file cannot
/// be written (naming it and the system's reason), std::invalid_argument as serialize_npy.
void write_npy(const std::filesystem::path& path, const NpyArray& array);

}  // namespace ropes::core
