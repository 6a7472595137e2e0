#pragma once
/// @file sha256.hpp
/// SHA-256 as specified in FIPS 180-4 (Secure Hash Standard, NIST, August 2015), written
/// here from the specification: the dataset container records a hash of every file it
/// writes and `DatasetReader::verify()` recomputes them. Checked against the NIST example
/// vectors and Python's hashlib (test/sha256_test.cpp).

#include <array>
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

#include "ropes_core/file_format_error.hpp"  // FileFormatError

namespace ropes::core {

/// An incremental SHA-256 computation: feed the message in pieces of any size with
/// update(), then finish() pads it and returns the 32-byte digest. The digest of a message
/// does not depend on how it was split. Cost: one 64-round compression per 64 bytes
/// (a few hundred MB/s). Not thread-safe: one object per message.
class Sha256 {
 public:
  Sha256();

  /// Appends `n` bytes at `data` to the message (`data` may be null when `n` is 0).
  /// Throws std::length_error when the message would exceed 2^61 - 1 bytes, the limit of
  /// FIPS 180-4's 64-bit bit count.
  void update(const void* data, std::size_t n);

  /// Pads the message, returns its digest (big-endian words H0..H7, as FIPS 180-4 prints
  /// them) and resets the object to the empty message, so it can hash another one.
  std::array<std::uint8_t, 32> finish();

 private:
  void compress(const std::uint8_t* block);  // one 64-byte block into state_
  void reset();

  std::array<std::uint32_t, 8> state_{};
  std::array<std::uint8_t, 64> buffer_{};  // a partial block awaiting more bytes
  std::size_t buffered_ = 0;               // bytes used in buffer_
  std::uint64_t length_ = 0;               // message bytes so far
};

/// Lower-case hexadecimal of a digest (64 characters).
std::string sha256_hex(const std::array<std::uint8_t, 32>& digest);

/// Lower-case hexadecimal SHA-256 of `n` bytes at `data`, as `sha256sum` prints it.
std::string sha256_hex(const void* data, std::size_t n);

/// Lower-case hexadecimal SHA-256 of the file at `path`, read in 1 MiB chunks (memory does
/// not grow with the file). Throws FileFormatError naming the file and the system's reason
/// when it cannot be opened or read.
std::string sha256_file(const std::filesystem::path& path);

}  // namespace ropes::core
