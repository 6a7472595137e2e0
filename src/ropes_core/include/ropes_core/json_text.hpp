#pragma once
/// @file json_text.hpp
/// JSON read from files: parsed with bounded nesting, and described in messages without
/// dumping it. Every JSON file of the workspace (configs, run.json, manifests, results) is read
/// through read_json_file or parse_json.
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>

#include "ropes_core/file_io.hpp"

namespace ropes::core {

/// The deepest nesting parse_json accepts.
inline constexpr int kMaxJsonDepth = 64;

/// Parses `text` into `out`. Returns "" on success, else what is wrong ("is not JSON: ...",
/// "nests deeper than 64 levels"), to be prefixed with the file's name. Nesting is bounded, so
/// that dumping or destroying the value later cannot overflow the stack.
std::string parse_json(const std::string& text, nlohmann::json* out);

/// `text` parsed as parse_json does, or a discarded value (is_discarded()) when it is not JSON
/// or nests too deep: for callers that treat a bad file like a missing one.
nlohmann::json parse_json_or_discarded(const std::string& text);

/// The JSON value in the file at `path`, read with read_text_file(path, max_bytes). Throws
/// FileFormatError naming the file: when it cannot be read, is larger than `max_bytes`, is not
/// JSON or nests deeper than kMaxJsonDepth.
nlohmann::json read_json_file(const std::filesystem::path& path,
                              std::uint64_t max_bytes = kMaxJsonFileBytes);

/// For a file that may be absent: read_json_file's value when `path` is a regular file, a
/// discarded value (is_discarded()) when it is missing or is not JSON. A file that is there
/// but cannot be read, or is larger than `max_bytes`, is still refused (FileFormatError).
nlohmann::json read_json_file_if_present(const std::filesystem::path& path,
                                         std::uint64_t max_bytes = kMaxJsonFileBytes);

/// A short description of a value read from a file, for messages: a string (its first 40
/// characters, quoted), a number, a boolean, or "a JSON object/array/null". Never dump() an
/// untrusted value instead: its recursion is as deep as the value.
std::string describe(const nlohmann::json& v);

/// The same, but an array is shown as its first 8 sizes ("[2,3,?]", "?" for an entry that is
/// not a non-negative integer): a shape or a pair of offsets.
std::string describe_sizes(const nlohmann::json& v);

}  // namespace ropes::core
