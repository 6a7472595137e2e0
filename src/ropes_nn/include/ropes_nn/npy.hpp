#pragma once
/// @file npy.hpp
/// NumPy .npy files (format versions 1.0, 2.0 and 3.0): read and write little-endian,
/// C-order arrays of u8, i32, i64, f32 and f64, the types the workspace's datasets and
/// fixtures use. Anything else is refused with a message, never guessed at.

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace ropes::nn {

/// Thrown for a file that is missing, unreadable, truncated, foreign or otherwise not what
/// the reader accepts. The message names the file, what was found and what was expected.
class FileFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

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

/// An n-dimensional array as stored in a file: element type, shape and the raw
/// little-endian bytes in C (row-major) order. data.size() == element_count() * itemsize.
struct NpyArray {
  DType dtype = DType::kF32;
  std::vector<std::int64_t> shape;  // empty shape: a scalar (one element)
  std::vector<std::uint8_t> data;

  /// Product of the shape (1 for a scalar).
  std::int64_t element_count() const;
};

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

/// Writes `bytes` to `path` through a temporary file and a rename (the files of this
/// library all go through it). Throws FileFormatError naming the file on failure.
/// The temporary is "<path>.tmp.<pid>", created new (a file or a symbolic link already at
/// that name is removed first, never written through), written, flushed and fsync'ed
/// before the rename; the directory is fsync'ed after it. A rename over a symbolic link at
/// `path` replaces the link, not its target. A write that fails (a full disk, a file-size
/// limit) removes the temporary and leaves what was at `path` as it was.
void write_file_atomically(const std::filesystem::path& path, const std::uint8_t* bytes,
                           std::size_t size);

/// True when `name` can name a file or directory as it is, never a path: 1 to `max_length`
/// letters, digits, '_', '-', '.', not starting with '.' (so no "..", no '/'). The config
/// names that tools name directories after must be such names.
bool is_plain_name(const std::string& name, std::size_t max_length = 128);

/// The limit on a JSON file that configures or records a run (configs, run.json, state and
/// result files) and on a metrics log, for read_text_file.
inline constexpr std::uint64_t kMaxJsonFileBytes = std::uint64_t{16} << 20;
inline constexpr std::uint64_t kMaxLogFileBytes = std::uint64_t{256} << 20;

/// The whole file at `path` as text. Throws FileFormatError naming the file: when it cannot
/// be opened or read (with the system's reason), is not a regular file, or holds more than
/// `max_bytes` (its size and the limit named; checked on the open file before anything of
/// that size is allocated, so a 2 GB file costs nothing).
std::string read_text_file(const std::filesystem::path& path, std::uint64_t max_bytes);

/// Removes the temporaries ("<name>.tmp.<pid>") that write_file_atomically calls of killed
/// processes left in `dir`; those of processes still running stay. With `file_name`, only
/// that file's ("<file_name>.tmp.<pid>"). A missing directory is not an error.
void remove_stale_temporaries(const std::filesystem::path& dir, const std::string& file_name = "");

}  // namespace ropes::nn
