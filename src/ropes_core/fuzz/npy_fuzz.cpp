// npy_fuzz: parse_npy (and parse_npy_header) on arbitrary bytes. A file that parses must
// serialize and parse back to the same array; a file that does not must be refused with a
// FileFormatError. Corpus: numpy's own files (test/fixtures, made by make_npy_fixtures.py).
#include <cstddef>
#include <cstdint>
#include <cstdlib>

#include "ropes_core/npy.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes::core;
  try {
    const NpyHeader header = parse_npy_header(data, size, "input.npy");
    if (header.data_offset > size && header.data_bytes > 0)
      std::abort();  // a header cannot start its data past what was read
  } catch (const FileFormatError&) {
  }
  NpyArray array;
  try {
    array = parse_npy(data, size, "input.npy");
  } catch (const FileFormatError&) {
    return 0;
  }
  const std::uint64_t expected =
      static_cast<std::uint64_t>(array.element_count()) * dtype_size(array.dtype);
  if (array.data.size() != expected)
    std::abort();
  const std::vector<std::uint8_t> bytes = serialize_npy(array);
  const NpyArray again = parse_npy(bytes.data(), bytes.size(), "again.npy");
  if (again.dtype != array.dtype || again.shape != array.shape || again.data != array.data)
    std::abort();
  return 0;
}
