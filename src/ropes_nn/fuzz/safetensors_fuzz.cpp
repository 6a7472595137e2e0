// safetensors_fuzz: parse_safetensors on arbitrary bytes. A file that parses must serialize
// and parse back to the same tensors and metadata; one that does not must be refused with a
// FileFormatError before any allocation the file's size does not justify.
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "ropes_nn/safetensors.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes::nn;
  Safetensors file;
  try {
    file = parse_safetensors(data, size, "input.safetensors");
  } catch (const ropes::core::FileFormatError&) {
    return 0;
  }
  const std::vector<std::uint8_t> bytes = serialize_safetensors(file);
  const Safetensors again = parse_safetensors(bytes.data(), bytes.size(), "again.safetensors");
  if (again.metadata != file.metadata || again.tensors.size() != file.tensors.size())
    std::abort();
  for (std::size_t i = 0; i < file.tensors.size(); ++i) {
    const auto& [name, array] = file.tensors[i];
    const ropes::core::NpyArray* found = again.find(name);
    if (found == nullptr || found->dtype != array.dtype || found->shape != array.shape ||
        found->data != array.data)
      std::abort();
  }
  return 0;
}
