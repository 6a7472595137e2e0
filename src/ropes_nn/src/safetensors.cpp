#include "ropes_nn/safetensors.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cstring>
#include <fstream>
#include <iterator>
#include <set>
#include <stdexcept>

#include "ropes_core/file_io.hpp"
#include "ropes_core/json_text.hpp"
#include "ropes_core/sha256.hpp"

namespace ropes::nn {

namespace {

using Json = nlohmann::json;

[[noreturn]] void safetensors_fail(const std::string& name, const std::string& what) {
  throw core::FileFormatError(name + ": " + what);
}

const char* dtype_code(core::DType d) {
  switch (d) {
    case core::DType::kU8:
      return "U8";
    case core::DType::kI32:
      return "I32";
    case core::DType::kI64:
      return "I64";
    case core::DType::kF32:
      return "F32";
    case core::DType::kF64:
      return "F64";
  }
  return "?";
}

bool parse_dtype(const std::string& code, core::DType* out) {
  static const std::pair<const char*, core::DType> kCodes[] = {{"U8", core::DType::kU8},
                                                               {"I32", core::DType::kI32},
                                                               {"I64", core::DType::kI64},
                                                               {"F32", core::DType::kF32},
                                                               {"F64", core::DType::kF64}};
  for (const auto& [text, dtype] : kCodes) {
    if (code == text) {
      *out = dtype;
      return true;
    }
  }
  return false;
}

// where the seal's 64 digits `digits` start in the header bytes [8, header_end): the one
// place the header holds "ropes.sha256":"<digits>"; npos when there is not exactly one
std::size_t seal_digits_at(const std::uint8_t* bytes, std::size_t header_end,
                           const std::string& digits) {
  const std::string needle = std::string("\"") + kSafetensorsSealKey + "\":\"" + digits + "\"";
  const char* begin = reinterpret_cast<const char*>(bytes) + 8;
  const char* end = reinterpret_cast<const char*>(bytes) + header_end;
  const char* first = std::search(begin, end, needle.begin(), needle.end());
  if (first == end || std::search(first + 1, end, needle.begin(), needle.end()) != end)
    return std::string::npos;
  return static_cast<std::size_t>(first - reinterpret_cast<const char*>(bytes)) + needle.size() -
         digits.size() - 1;
}

bool is_hex_digest(const std::string& text) {
  return text.size() == 64 && std::all_of(text.begin(), text.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

// checks the seal `recorded` of the file image bytes[0, size) (header up to header_end)
void check_seal(const std::uint8_t* bytes, std::size_t size, std::size_t header_end,
                const std::string& recorded, const std::string& name) {
  const std::string where = std::string("__metadata__['") + kSafetensorsSealKey + "']";
  if (!is_hex_digest(recorded)) {
    safetensors_fail(name, where + " is " + core::describe(Json(recorded)) +
                               "; expected 64 lower-case hexadecimal digits");
  }
  const std::size_t at = seal_digits_at(bytes, header_end, recorded);
  if (at == std::string::npos) {
    safetensors_fail(name,
                     where + " is not written as \"" + kSafetensorsSealKey +
                         "\":\"<digits>\" exactly once in the header; the seal cannot be checked");
  }
  core::Sha256 hash;
  hash.update(bytes, at);
  const std::string zeros(64, '0');
  hash.update(reinterpret_cast<const std::uint8_t*>(zeros.data()), zeros.size());
  hash.update(bytes + at + 64, size - at - 64);
  const std::string actual = core::sha256_hex(hash.finish());
  if (actual != recorded) {
    safetensors_fail(name, "sha256 is " + actual + "; its seal records " + recorded +
                               " (the file changed after it was written)");
  }
}

}  // namespace

const core::NpyArray* Safetensors::find(const std::string& name) const {
  for (const auto& [key, array] : tensors) {
    if (key == name)
      return &array;
  }
  return nullptr;
}

std::vector<std::uint8_t> serialize_safetensors(const Safetensors& file, bool sealed) {
  Json header = Json::object();
  if (sealed && file.metadata.count(kSafetensorsSealKey)) {
    throw std::invalid_argument(std::string("serialize_safetensors: metadata key '") +
                                kSafetensorsSealKey + "' is reserved for the seal");
  }
  if (!file.metadata.empty() || sealed)
    header["__metadata__"] = file.metadata;
  if (sealed)
    header["__metadata__"][kSafetensorsSealKey] = std::string(64, '0');
  std::set<std::string> names;
  std::uint64_t offset = 0;
  for (const auto& [name, array] : file.tensors) {
    if (name.empty() || name == "__metadata__" || !names.insert(name).second) {
      throw std::invalid_argument("serialize_safetensors: tensor name '" + name +
                                  "' is empty, reserved or repeated");
    }
    std::uint64_t bytes = 0;
    if (!core::checked_byte_count(array.dtype, array.shape, &bytes) || bytes != array.data.size()) {
      throw std::invalid_argument("serialize_safetensors: tensor '" + name + "' has " +
                                  std::to_string(array.data.size()) +
                                  " data bytes, which do not match its shape");
    }
    header[name] = {{"dtype", dtype_code(array.dtype)},
                    {"shape", array.shape},
                    {"data_offsets", {offset, offset + bytes}}};
    offset += bytes;
  }
  std::string text = header.dump();
  text.append((8 - text.size() % 8) % 8, ' ');
  std::vector<std::uint8_t> out;
  out.reserve(8 + text.size() + offset);
  for (int i = 0; i < 8; ++i)
    out.push_back(static_cast<std::uint8_t>(text.size() >> (8 * i)));
  out.insert(out.end(), text.begin(), text.end());
  for (const auto& [name, array] : file.tensors) {
    out.insert(out.end(), array.data.begin(), array.data.end());
  }
  if (sealed) {
    // the digits are '0' while hashing; nlohmann writes the entry as "key":"value"
    const std::size_t at = seal_digits_at(out.data(), 8 + text.size(), std::string(64, '0'));
    if (at == std::string::npos)
      throw std::logic_error("serialize_safetensors: the seal is not in the header as written");
    const std::string hex = core::sha256_hex(out.data(), out.size());
    std::copy(hex.begin(), hex.end(), out.begin() + static_cast<std::ptrdiff_t>(at));
  }
  return out;
}

bool is_sealed(const Safetensors& file) {
  return file.metadata.count(kSafetensorsSealKey) != 0;
}

Safetensors parse_safetensors(const std::uint8_t* bytes, std::size_t size,
                              const std::string& name) {
  if (size < 8)
    safetensors_fail(name, "shorter than the 8-byte header length of a .safetensors file");
  std::uint64_t header_length = 0;
  for (int i = 0; i < 8; ++i)
    header_length |= static_cast<std::uint64_t>(bytes[i]) << (8 * i);
  if (header_length > kSafetensorsMaxHeaderBytes) {
    safetensors_fail(
        name, "header length " + std::to_string(header_length) + " exceeds the limit of " +
                  std::to_string(kSafetensorsMaxHeaderBytes) + " bytes (not a .safetensors file?)");
  }
  if (header_length > size - 8) {
    safetensors_fail(name, "header length " + std::to_string(header_length) +
                               " runs past the end of the " + std::to_string(size) + "-byte file");
  }
  const std::uint64_t data_size = size - 8 - header_length;

  Json header;
  const std::string problem = core::parse_json(
      std::string(reinterpret_cast<const char*>(bytes) + 8, header_length), &header);
  if (!problem.empty())
    safetensors_fail(name, "the header " + problem);
  if (!header.is_object())
    safetensors_fail(name, "the header is not a JSON object");

  Safetensors file;
  // entries, checked, then sorted by offset to prove they tile the data exactly
  struct Entry {
    std::string key;
    core::NpyArray array;
    std::uint64_t begin, end;
  };
  std::vector<Entry> entries;
  for (const auto& [key, value] : header.items()) {
    if (key == "__metadata__") {
      if (!value.is_object())
        safetensors_fail(name, "__metadata__ is not an object of strings");
      for (const auto& [mk, mv] : value.items()) {
        if (!mv.is_string())
          safetensors_fail(name, "__metadata__['" + mk + "'] is not a string");
        file.metadata[mk] = mv.get<std::string>();
      }
      continue;
    }
    const std::string where = "tensor '" + key + "'";
    if (!value.is_object() || !value.contains("dtype") || !value.contains("shape") ||
        !value.contains("data_offsets")) {
      safetensors_fail(name, where + " lacks dtype, shape or data_offsets");
    }
    Entry e{key, {}, 0, 0};
    const Json& dtype = value["dtype"];
    if (!dtype.is_string() || !parse_dtype(dtype.get<std::string>(), &e.array.dtype)) {
      safetensors_fail(name, where + " has dtype " + core::describe(dtype) +
                                 "; expected U8, I32, I64, F32 or F64");
    }
    const Json& shape = value["shape"];
    if (!shape.is_array() || shape.size() > static_cast<std::size_t>(core::kNpyMaxRank)) {
      safetensors_fail(name, where + " has shape " + core::describe_sizes(shape) +
                                 "; expected a list of at most " +
                                 std::to_string(core::kNpyMaxRank) + " sizes");
    }
    for (const Json& d : shape) {
      if (!d.is_number_unsigned())
        safetensors_fail(name, where + " has shape " + core::describe_sizes(shape));
      e.array.shape.push_back(
          static_cast<std::int64_t>(std::min<std::uint64_t>(d.get<std::uint64_t>(), INT64_MAX)));
    }
    const Json& offsets = value["data_offsets"];
    if (!offsets.is_array() || offsets.size() != 2 || !offsets[0].is_number_unsigned() ||
        !offsets[1].is_number_unsigned()) {
      safetensors_fail(name, where + " has data_offsets " + core::describe_sizes(offsets) +
                                 "; expected [begin, end]");
    }
    e.begin = offsets[0].get<std::uint64_t>();
    e.end = offsets[1].get<std::uint64_t>();
    std::uint64_t nbytes = 0;
    if (!core::checked_byte_count(e.array.dtype, e.array.shape, &nbytes) || e.end < e.begin ||
        e.end - e.begin != nbytes) {
      safetensors_fail(name, where + " has data_offsets " + core::describe_sizes(offsets) +
                                 " for a " + dtype_code(e.array.dtype) + " " +
                                 core::describe_sizes(shape) + " tensor of " +
                                 std::to_string(nbytes) + " bytes");
    }
    entries.push_back(std::move(e));
  }
  std::sort(entries.begin(), entries.end(),
            [](const Entry& a, const Entry& b) { return a.begin < b.begin; });
  std::uint64_t expected = 0;
  for (const Entry& e : entries) {
    if (e.begin != expected) {
      safetensors_fail(name, "tensor '" + e.key + "' starts at byte " + std::to_string(e.begin) +
                                 "; expected " + std::to_string(expected) +
                                 " (offsets must tile the data)");
    }
    expected = e.end;
  }
  if (expected != data_size) {
    safetensors_fail(name, "the tensors cover " + std::to_string(expected) +
                               " bytes but the file holds " + std::to_string(data_size) +
                               " data bytes");
  }
  const auto seal = file.metadata.find(kSafetensorsSealKey);
  if (seal != file.metadata.end())
    check_seal(bytes, size, 8 + header_length, seal->second, name);
  const std::uint8_t* data = bytes + 8 + header_length;
  for (Entry& e : entries) {
    e.array.data.assign(data + e.begin, data + e.end);
    file.tensors.emplace_back(std::move(e.key), std::move(e.array));
  }
  return file;
}

Safetensors read_safetensors(const std::filesystem::path& path) {
  const std::string name = path.string();
  std::ifstream in(path, std::ios::binary);
  if (!in)
    safetensors_fail(name, "cannot open");
  const std::vector<std::uint8_t> bytes((std::istreambuf_iterator<char>(in)),
                                        std::istreambuf_iterator<char>());
  return parse_safetensors(bytes.data(), bytes.size(), name);
}

void write_safetensors(const std::filesystem::path& path, const Safetensors& file, bool sealed) {
  const std::vector<std::uint8_t> bytes = serialize_safetensors(file, sealed);
  core::write_file_atomically(path, bytes.data(), bytes.size());
}

}  // namespace ropes::nn
