#pragma once
/// @file file_format_error.hpp
/// The exception types of the workspace's file readers: FileFormatError, and ConfigError for
/// a config (a dataset config of ropes_sim, an experiment config of ropes_crl).
#include <stdexcept>

namespace ropes::core {

/// Thrown for a file that is missing, unreadable, truncated, foreign or otherwise not what
/// the reader accepts. The message names the file, what was found and what was expected.
class FileFormatError : public std::runtime_error {
 public:
  using std::runtime_error::runtime_error;
};

/// Thrown for a config that cannot be used: a field missing, of the wrong type or out of
/// range, or a config name that is neither a file nor an installed config. The message names
/// the file (or the source of the JSON), the field, the value and what was expected. A
/// FileFormatError, as every refusal of a file in the workspace is.
class ConfigError : public FileFormatError {
 public:
  using FileFormatError::FileFormatError;
};

}  // namespace ropes::core
