#pragma once
/// @file file_format_error.hpp
/// The one exception type of the workspace's file readers.
#include <stdexcept>

namespace ropes::core {

/// Thrown for a file that is missing, unreadable, truncated, foreign or otherwise not what
/// the reader accepts. The message names the file, what was found and what was expected.
class FileFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

}  // namespace ropes::core
