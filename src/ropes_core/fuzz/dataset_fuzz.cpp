// dataset_fuzz: a dataset directory from arbitrary bytes, opened and read as a trainer does.
// The input's sections (fuzz_input.hpp) are the files: "" is manifest.json, "marker" is
// shards/00000.json, "x" and "y" are shards/x-00000.npy and shards/y-00000.npy. The harness
// checks dataset_shard_complete() for the columns x f32 [2] and y u8 [], then opens the
// directory with DatasetReader, reads every row of every column it names, gathers rows in
// reverse and verifies the hashes. Each step either works or is refused with a
// FileFormatError (or, for a row range the reader's own rows() rule out, not attempted).
// Corpus: small complete datasets (ropes_nn_fuzz_make_corpus).
#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <map>
#include <string>
#include <vector>

#include "ropes_core/dataset.hpp"
#include "ropes_core/fuzz_input.hpp"
#include "ropes_core/npy.hpp"

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes::core;
  static const fuzz::ScratchDir scratch;
  static const std::map<std::string, std::string> files = {{"", "manifest.json"},
                                                           {"marker", "shards/00000.json"},
                                                           {"x", "shards/x-00000.npy"},
                                                           {"y", "shards/y-00000.npy"}};
  scratch.clear();
  for (const fuzz::Section& section : fuzz::split_sections(data, size)) {
    const auto it = files.find(section.name);
    if (it != files.end())
      scratch.write(it->second, section.bytes);
  }
  const std::vector<ColumnSpec> columns = {{"x", DType::kF32, {2}}, {"y", DType::kU8, {}}};
  dataset_shard_complete(scratch.path(), 0, columns);

  try {
    const DatasetReader reader = DatasetReader::open(scratch.path());
    const std::int64_t rows = reader.rows();
    if (rows < 0)
      std::abort();
    for (const ColumnSpec& column : reader.columns()) {
      if (rows <= 1024) {
        const NpyArray all = reader.read_rows(column.name, 0, rows);
        std::vector<std::int64_t> reversed;
        for (std::int64_t r = rows - 1; r >= 0; --r)
          reversed.push_back(r);
        const NpyArray gathered = reader.read_rows_at(column.name, reversed);
        if (all.data.size() != gathered.data.size())
          std::abort();
      }
    }
    reader.verify();
  } catch (const FileFormatError&) {
  }
  return 0;
}
