#pragma once
/// @file safetensors.hpp
/// .safetensors files, as the format is published: an 8-byte little-endian header length N,
/// N bytes of JSON ({"__metadata__": {string: string}, name: {"dtype", "shape",
/// "data_offsets": [begin, end]}, ...}), then the tensors' raw little-endian bytes, offsets
/// relative to the end of the header. Files written here open in Python's safetensors and
/// PyTorch; reading checks everything the format promises before allocating. Modules and
/// training states are saved through it by checkpoint.hpp.

#include <cstdint>
#include <filesystem>
#include <map>
#include <string>
#include <utility>
#include <vector>

#include "ropes_core/npy.hpp"

namespace ropes::nn {

/// Named arrays in file order, and the free-form string metadata.
struct Safetensors {
  std::vector<std::pair<std::string, core::NpyArray>> tensors;
  std::map<std::string, std::string> metadata;

  /// The array called `name`; core::FileFormatError-free lookup: nullptr when absent.
  const core::NpyArray* find(const std::string& name) const;
};

/// Limits against hostile files.
inline constexpr std::uint64_t kSafetensorsMaxHeaderBytes = 100u << 20;  // as the reference

/// The metadata key of a sealed file's own SHA-256 (64 lower-case hexadecimal digits): the
/// hash of the file's bytes as written, with those 64 digits read as '0's. A sealed file
/// is still a plain .safetensors file for every other reader; parse_safetensors checks the
/// seal of every file that has one, so a byte changed anywhere after writing is found.
inline constexpr const char* kSafetensorsSealKey = "ropes.sha256";

/// The bytes of a .safetensors file: tensors in the given order, the header padded with
/// spaces to a multiple of 8 bytes; `sealed`: with the metadata entry kSafetensorsSealKey.
/// Throws std::invalid_argument for an empty or duplicate name, the reserved name
/// "__metadata__", an array whose data does not match its shape, or (sealed) metadata that
/// already uses kSafetensorsSealKey.
std::vector<std::uint8_t> serialize_safetensors(const Safetensors& file, bool sealed = false);

/// Parses a whole file image. `name` is used in messages. Throws core::FileFormatError for a
/// truncated file, a header length over kSafetensorsMaxHeaderBytes or past the end, JSON
/// that does not parse or is not an object, an entry without dtype/shape/data_offsets, a
/// dtype other than U8, I32, I64, F32, F64, offsets that do not match the shape, overlap,
/// leave gaps or do not end at the end of the file, and metadata values that are not strings;
/// for a sealed file (metadata kSafetensorsSealKey), a seal that is not 64 hexadecimal
/// digits or not the file's SHA-256 ("the file changed after it was written"). The parsed
/// metadata keeps the seal's entry. Cost: a sealed file is hashed once (about 0.5 GB/s).
Safetensors parse_safetensors(const std::uint8_t* bytes, std::size_t size, const std::string& name);

/// Reads and parses a whole file (parse_safetensors). Throws core::FileFormatError naming the file
/// when it cannot be opened or read.
Safetensors read_safetensors(const std::filesystem::path& path);
/// Writes through a temporary file and a rename; `sealed` as serialize_safetensors.
void write_safetensors(const std::filesystem::path& path, const Safetensors& file,
                       bool sealed = false);

/// True when the parsed file carries a seal (which parse_safetensors has checked).
bool is_sealed(const Safetensors& file);

}  // namespace ropes::nn
