#pragma once
/// @file file_io.hpp
/// Bounded reads and atomic writes: every file the workspace writes goes through
/// write_file_atomically, every text file it reads through read_text_file.
#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <string>

namespace ropes::core {

/// Writes `bytes` to `path` through a temporary file and a rename (the files of this
/// library all go through it). Throws FileFormatError naming the file on failure.
/// The temporary is "<path>.tmp.<pid>", created new (a file or a symbolic link already at
/// that name is removed first, never written through), written, flushed and fsync'ed
/// before the rename; the directory is fsync'ed after it. A rename over a symbolic link at
/// `path` replaces the link, not its target. A write that fails (a full disk, a file-size
/// limit) removes the temporary and leaves what was at `path` as it was.
void write_file_atomically(const std::filesystem::path& path, const std::uint8_t* bytes,
                           std::size_t size);

/// The same for a text.
inline void write_text_file_atomically(const std::filesystem::path& path, const std::string& text) {
  write_file_atomically(path, reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
}

/// The limit on a JSON file that configures or records a run (configs, run.json, state and
/// result files) and on a metrics log, for read_text_file.
inline constexpr std::uint64_t kMaxJsonFileBytes = std::uint64_t{16} << 20;
inline constexpr std::uint64_t kMaxLogFileBytes = std::uint64_t{256} << 20;

/// The whole file at `path` as text. Throws FileFormatError naming the file: when it cannot
/// be opened or read (with the system's reason), is not a regular file, or holds more than
/// `max_bytes` (its size and the limit named; checked on the open file before anything of
/// that size is allocated, so a 2 GB file costs nothing).
std::string read_text_file(const std::filesystem::path& path, std::uint64_t max_bytes);

/// Whether `path` is a regular file (a link to one included). A path that cannot be looked
/// at (a name too long, a loop of links, a folder without permission) is not: never throws,
/// where std::filesystem::is_regular_file(path) would. Call it qualified (core::is_regular_file):
/// unqualified, argument-dependent lookup also finds the std::filesystem overloads.
bool is_regular_file(const std::filesystem::path& path) noexcept;

/// Removes the temporaries ("<name>.tmp.<pid>") that write_file_atomically calls of killed
/// processes left in `dir`; those of processes still running stay. With `file_name`, only
/// that file's ("<file_name>.tmp.<pid>"). A missing directory is not an error.
void remove_stale_temporaries(const std::filesystem::path& dir, const std::string& file_name = "");

}  // namespace ropes::core
