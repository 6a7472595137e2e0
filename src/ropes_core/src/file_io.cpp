#include "ropes_core/file_io.hpp"

#include <fcntl.h>
#include <signal.h>
#include <sys/stat.h>
#include <unistd.h>

#include <cerrno>
#include <charconv>
#include <cstdio>
#include <cstring>

#include "file_errors.hpp"
#include "ropes_core/file_format_error.hpp"

namespace ropes::core {

namespace detail {

void fail(const std::string& name, const std::string& what) {
  throw FileFormatError(name + ": " + what);
}

}  // namespace detail

using detail::fail;

void write_file_atomically(const std::filesystem::path& path, const std::uint8_t* bytes,
                           std::size_t size) {
  const std::string name = path.string();
  const std::string temp = name + ".tmp." + std::to_string(::getpid());
  {
    // a new file, never one that is there: not a temporary of an earlier process that had
    // this pid, and not a link planted at the name (O_NOFOLLOW), which would be written
    // through to its target; either is removed (the link itself) and the file made anew
    constexpr int kFlags = O_WRONLY | O_CREAT | O_EXCL | O_NOFOLLOW | O_CLOEXEC;
    int fd = ::open(temp.c_str(), kFlags, 0666);
    if (fd < 0 && errno == EEXIST && ::unlink(temp.c_str()) == 0)
      fd = ::open(temp.c_str(), kFlags, 0666);
    if (fd < 0)
      fail(name, std::string("cannot write ") + temp + ": " + std::strerror(errno));
    std::size_t done = 0;
    bool ok = true;
    while (ok && done < size) {
      const ssize_t n = ::write(fd, bytes + done, size - done);
      if (n > 0)
        done += static_cast<std::size_t>(n);
      else if (n < 0 && errno == EINTR)
        continue;
      else
        ok = false;  // errno says why (ENOSPC, EFBIG, EIO, ...)
    }
    ok = ok && ::fsync(fd) == 0;
    const int write_errno = errno;
    const bool closed = ::close(fd) == 0;
    if (!ok || !closed) {
      const std::string reason = std::strerror(ok ? errno : write_errno);
      ::unlink(temp.c_str());
      fail(name, "writing failed: " + reason);
    }
  }
  if (std::rename(temp.c_str(), name.c_str()) != 0) {
    const std::string reason = std::strerror(errno);
    std::remove(temp.c_str());
    fail(name, "cannot rename " + temp + " into place: " + reason);
  }
  // the rename itself reaches the disk with the directory (best effort: some file systems
  // refuse fsync on a directory, and the file is in place either way)
  const std::filesystem::path parent = path.has_parent_path() ? path.parent_path() : ".";
  const int dir = ::open(parent.c_str(), O_RDONLY | O_DIRECTORY | O_CLOEXEC);
  if (dir >= 0) {
    ::fsync(dir);
    ::close(dir);
  }
}

std::string read_text_file(const std::filesystem::path& path, std::uint64_t max_bytes) {
  const std::string name = path.string();
  const int fd = ::open(name.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0)
    fail(name, std::string("cannot open: ") + std::strerror(errno));
  struct Closer {
    int fd;
    ~Closer() { ::close(fd); }
  } closer{fd};
  struct stat st {};
  if (::fstat(fd, &st) != 0)
    fail(name, std::string("cannot read: ") + std::strerror(errno));
  if (!S_ISREG(st.st_mode))
    fail(name, "is not a regular file");
  const auto size = static_cast<std::uint64_t>(st.st_size);
  if (size > max_bytes) {
    fail(name, "holds " + std::to_string(size) + " bytes; expected at most " +
                   std::to_string(max_bytes) + " for a file of this kind");
  }
  std::string text(static_cast<std::size_t>(size), '\0');
  std::size_t done = 0;
  while (done < text.size()) {
    const ssize_t n = ::pread(fd, text.data() + done, text.size() - done, static_cast<off_t>(done));
    if (n < 0 && errno == EINTR)
      continue;
    if (n < 0)
      fail(name, std::string("cannot read: ") + std::strerror(errno));
    if (n == 0)
      break;  // it shrank while being read: what is there
    done += static_cast<std::size_t>(n);
  }
  text.resize(done);
  return text;
}

bool is_regular_file(const std::filesystem::path& path) noexcept {
  std::error_code ec;
  return std::filesystem::is_regular_file(path, ec);
}

void remove_stale_temporaries(const std::filesystem::path& dir, const std::string& file_name) {
  std::error_code ec;
  if (!std::filesystem::is_directory(dir, ec))
    return;
  for (const auto& entry : std::filesystem::directory_iterator(dir, ec)) {
    const std::string name = entry.path().filename().string();
    const auto at = name.rfind(".tmp.");
    if (at == std::string::npos || (!file_name.empty() && name.compare(0, at, file_name) != 0) ||
        (!file_name.empty() && at != file_name.size())) {
      continue;
    }
    const std::string digits = name.substr(at + 5);
    long pid = 0;
    const auto [end, error] = std::from_chars(digits.data(), digits.data() + digits.size(), pid);
    if (error != std::errc() || end != digits.data() + digits.size() || pid <= 0)
      continue;
    // only a process that no longer exists leaves its temporary for good
    if (::kill(static_cast<pid_t>(pid), 0) == -1 && errno == ESRCH)
      std::filesystem::remove(entry.path(), ec);
  }
}

}  // namespace ropes::core
