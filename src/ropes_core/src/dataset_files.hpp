#pragma once
// The dataset container's file access (private to ropes_core): descriptors closed on
// destruction, exact positioned reads, .npy headers and column files checked against their
// records, small text files read whole; every error a FileFormatError naming the file.
#include <unistd.h>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>
#include <utility>

#include "ropes_core/dataset.hpp"
#include "ropes_core/npy.hpp"

namespace ropes::core::detail {

namespace fs = std::filesystem;

// an open file descriptor, closed on destruction
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  Fd(Fd&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}
  Fd& operator=(Fd&& other) noexcept {
    if (this != &other) {
      close();
      fd_ = std::exchange(other.fd_, -1);
    }
    return *this;
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() { close(); }
  int get() const { return fd_; }

 private:
  void close() {
    if (fd_ >= 0)
      ::close(fd_);
    fd_ = -1;
  }
  int fd_ = -1;
};

Fd open_file(const std::string& name, const std::string& context);

std::uint64_t size_of(const Fd& fd, const std::string& name);

// exactly `n` bytes at `offset`, or a FileFormatError naming the file
void pread_all(int fd, void* out, std::size_t n, std::uint64_t offset, const std::string& name);

// the .npy header of an open file of `size` bytes: only the header's bytes are read
NpyHeader read_header(const Fd& fd, std::uint64_t size, const std::string& name);

// checks an open column file against its column, rows and recorded size; returns its header
NpyHeader check_column_file(const Fd& fd, const std::string& name, const ColumnSpec& column,
                            std::int64_t rows, std::uint64_t recorded_bytes,
                            const std::string& context);

// the descriptors this process holds open now (those listed in /proc/self/fd, less the one
// that lists them); 0 when that cannot be read
std::uint64_t count_open_descriptors();

// core::read_text_file (file_io.hpp), its message with `context` after the file's name
std::string read_small_file(const fs::path& path, std::uint64_t max_bytes,
                            const std::string& context);

}  // namespace ropes::core::detail
