#include "dataset_files.hpp"

#include <fcntl.h>
#include <sys/stat.h>
#include <unistd.h>

#include <algorithm>
#include <cerrno>
#include <cstring>
#include <system_error>
#include <vector>

#include "dataset_layout.hpp"
#include "ropes_core/file_format_error.hpp"
#include "ropes_core/file_io.hpp"

namespace ropes::core::detail {

Fd open_file(const std::string& name, const std::string& context) {
  const int fd = ::open(name.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int error = errno;
    fail(name, context + "cannot open: " + std::strerror(error) +
                   (error == EMFILE ? " (a reader holds one descriptor per column per shard: "
                                      "raise `ulimit -n` or write fewer, larger shards)"
                                    : ""));
  }
  return Fd(fd);
}

std::uint64_t size_of(const Fd& fd, const std::string& name) {
  struct stat info {};
  if (::fstat(fd.get(), &info) != 0)
    fail(name, std::string("cannot stat: ") + std::strerror(errno));
  return static_cast<std::uint64_t>(info.st_size);
}

// exactly `n` bytes at `offset`, or a FileFormatError naming the file
void pread_all(int fd, void* out, std::size_t n, std::uint64_t offset, const std::string& name) {
  auto* p = static_cast<std::uint8_t*>(out);
  while (n > 0) {
    const ssize_t got = ::pread(fd, p, n, static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR)
      continue;
    if (got < 0) {
      fail(name, "reading " + std::to_string(n) + " bytes at byte " + std::to_string(offset) +
                     " failed: " + std::strerror(errno));
    }
    if (got == 0) {
      fail(name, "ends at byte " + std::to_string(offset) + ", " + std::to_string(n) +
                     " bytes short (truncated after the dataset was opened?)");
    }
    p += got;
    n -= static_cast<std::size_t>(got);
    offset += static_cast<std::uint64_t>(got);
  }
}

// the .npy header of an open file of `size` bytes: only the header's bytes are read
NpyHeader read_header(const Fd& fd, std::uint64_t size, const std::string& name) {
  // magic (6), version (2), then a 2-byte (1.0) or 4-byte (2.0, 3.0) length
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(std::min<std::uint64_t>(size, 12)));
  pread_all(fd.get(), bytes.data(), bytes.size(), 0, name);
  std::uint64_t want = bytes.size();
  if (bytes.size() == 12) {
    const bool v1 = bytes[6] == 1;
    std::uint64_t length = 0;
    for (int i = 0; i < (v1 ? 2 : 4); ++i)
      length |= static_cast<std::uint64_t>(bytes[8 + i]) << (8 * i);
    // a length over the limit is refused by the parser from the prefix alone
    if (length <= kNpyMaxHeaderBytes)
      want = std::min<std::uint64_t>(size, (v1 ? 10 : 12) + length);
  }
  if (want > bytes.size()) {
    bytes.resize(static_cast<std::size_t>(want));
    pread_all(fd.get(), bytes.data(), bytes.size(), 0, name);
  }
  return parse_npy_header(bytes.data(), bytes.size(), name);
}

// checks an open column file against its column, rows and recorded size; returns its header
NpyHeader check_column_file(const Fd& fd, const std::string& name, const ColumnSpec& column,
                            std::int64_t rows, std::uint64_t recorded_bytes,
                            const std::string& context) {
  const std::uint64_t size = size_of(fd, name);
  NpyHeader header = read_header(fd, size, name);
  if (header.dtype != column.dtype) {
    fail(name, context + "dtype is " + dtype_name(header.dtype) + "; column '" + column.name +
                   "' expects " + dtype_name(column.dtype));
  }
  const std::vector<std::int64_t> expected = file_shape(rows, column.row_shape);
  if (header.shape != expected) {
    fail(name, context + "shape is " + shape_text(header.shape) + "; column '" + column.name +
                   "' expects [rows, row_shape...] = " + shape_text(expected));
  }
  if (size != header.data_offset + header.data_bytes) {
    fail(name, context + "holds " + std::to_string(size) + " bytes; its header needs " +
                   std::to_string(header.data_offset + header.data_bytes) + " (truncated?)");
  }
  if (size != recorded_bytes) {
    fail(name, context + "holds " + std::to_string(size) + " bytes; the record says " +
                   std::to_string(recorded_bytes));
  }
  return header;
}

// the descriptors this process holds open now (those listed in /proc/self/fd, less the one
// that lists them); 0 when that cannot be read
std::uint64_t count_open_descriptors() {
  std::error_code ec;
  std::uint64_t n = 0;
  for (fs::directory_iterator it("/proc/self/fd", ec), end; !ec && it != end; it.increment(ec))
    ++n;
  return n > 0 ? n - 1 : 0;
}

// core::read_text_file, its message with `context` after the file's name
std::string read_small_file(const fs::path& path, std::uint64_t max_bytes,
                            const std::string& context) {
  try {
    return read_text_file(path, max_bytes);
  } catch (const FileFormatError& e) {
    const std::string prefix = path.string() + ": ";
    std::string what = e.what();
    if (what.rfind(prefix, 0) == 0)
      what.insert(prefix.size(), context);
    throw FileFormatError(what);
  }
}

}  // namespace ropes::core::detail
