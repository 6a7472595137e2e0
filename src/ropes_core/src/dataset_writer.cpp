// The dataset container's writer: shards (column files and a marker) and the manifest.
#include "ropes_core/dataset.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <set>
#include <stdexcept>
#include <utility>

#include "dataset_files.hpp"
#include "dataset_layout.hpp"
#include "ropes_core/file_io.hpp"
#include "ropes_core/json_text.hpp"
#include "ropes_core/sha256.hpp"

namespace ropes::core {

using namespace detail;

void write_dataset_shard(const fs::path& dir, int shard, const std::vector<ColumnSpec>& columns,
                         const std::vector<NpyArray>& data, const std::string& dataset_id) {
  constexpr const char* kFunction = "write_dataset_shard";
  check_columns(kFunction, columns);
  check_shard_number(kFunction, shard);
  if (data.size() != columns.size()) {
    throw std::invalid_argument(std::string(kFunction) + ": " + std::to_string(data.size()) +
                                " arrays for " + std::to_string(columns.size()) + " columns (" +
                                column_list(columns) + "); expected one array per column");
  }

  // every array checked before anything is written
  std::int64_t rows = 0;
  for (std::size_t i = 0; i < columns.size(); ++i) {
    const ColumnSpec& column = columns[i];
    const NpyArray& array = data[i];
    const std::string what = std::string(kFunction) + ": column '" + column.name + "' ";
    if (array.dtype != column.dtype) {
      throw std::invalid_argument(what + "has dtype " + dtype_name(array.dtype) + "; expected " +
                                  dtype_name(column.dtype));
    }
    const std::int64_t array_rows = array.shape.empty() ? 0 : array.shape[0];
    if (array.shape.empty() || array.shape != file_shape(array_rows, column.row_shape)) {
      throw std::invalid_argument(what + "has shape " + shape_text(array.shape) +
                                  "; expected [rows, row_shape...] = [rows" +
                                  (column.row_shape.empty() ? "" : ", ") +
                                  shape_text(column.row_shape).substr(1));
    }
    if (array_rows <= 0)
      throw std::invalid_argument(what + "has 0 rows; expected at least 1");
    if (i > 0 && array_rows != rows) {
      throw std::invalid_argument(what + "has " + std::to_string(array_rows) + " rows; expected " +
                                  std::to_string(rows) + ", as column '" + columns[0].name +
                                  "' has");
    }
    rows = array_rows;
    std::uint64_t bytes = 0;
    if (!checked_byte_count(array.dtype, array.shape, &bytes) || bytes != array.data.size()) {
      throw std::invalid_argument(what + "holds " + std::to_string(array.data.size()) +
                                  " data bytes; its shape " + shape_text(array.shape) + " needs " +
                                  std::to_string(bytes));
    }
  }

  // no marker while the files change, so a crash here leaves the shard incomplete
  const fs::path shards = dir / "shards";
  std::error_code ec;
  // a link there would take the shards out of the dataset's directory
  if (fs::is_symlink(shards, ec)) {
    fail(shards.string(),
         "is a symbolic link; a dataset's shards are written only inside its "
         "directory (replace the link with a directory)");
  }
  fs::create_directories(shards, ec);
  if (ec)
    fail(shards.string(), "cannot create the directory: " + ec.message());
  const fs::path marker = marker_path(dir, shard);
  fs::remove(marker, ec);
  if (ec)
    fail(marker.string(), "cannot remove the old marker: " + ec.message());

  // the column files, then the marker that records them
  ShardRecord record;
  record.rows = rows;
  record.dataset = dataset_id;
  for (std::size_t i = 0; i < columns.size(); ++i) {
    const std::vector<std::uint8_t> bytes = serialize_npy(data[i]);
    FileRecord f{column_file(columns[i].name, shard), bytes.size(),
                 sha256_hex(bytes.data(), bytes.size())};
    write_file_atomically(dir / f.path, bytes.data(), bytes.size());
    record.files.push_back(std::move(f));
  }
  const std::string text = shard_json(record, columns).dump(2) + "\n";
  write_text_file_atomically(marker, text);
}

bool dataset_shard_complete(const fs::path& dir, int shard, const std::vector<ColumnSpec>& columns,
                            const std::string& dataset_id) {
  check_columns("dataset_shard_complete", columns);
  check_shard_number("dataset_shard_complete", shard);
  // an incomplete shard is an expected state here, not an error
  return dataset_shard_problem(dir, shard, columns, dataset_id).empty();
}

std::string dataset_shard_problem(const fs::path& dir, int shard,
                                  const std::vector<ColumnSpec>& columns,
                                  const std::string& dataset_id, bool check_sha256) {
  check_columns("dataset_shard_problem", columns);
  check_shard_number("dataset_shard_problem", shard);
  try {
    const ShardRecord record = read_complete_shard(dir, shard, columns, dataset_id);
    if (check_sha256) {
      for (const FileRecord& f : record.files) {
        const fs::path file = dir / f.path;
        const std::string actual = sha256_file(file);
        if (actual != f.sha256) {
          fail(file.string(), "sha256 is " + actual + "; the marker of shard " +
                                  std::to_string(shard) + " records " + f.sha256 +
                                  " (the file changed after it was written)");
        }
      }
    }
    return "";
  } catch (const FileFormatError& e) {
    return e.what();
  }
}

void write_dataset_manifest(const fs::path& dir, const std::vector<ColumnSpec>& columns,
                            int shard_count, const std::string& metadata_json,
                            const std::string& dataset_id) {
  constexpr const char* kFunction = "write_dataset_manifest";
  check_columns(kFunction, columns);
  if (shard_count < 1) {
    throw std::invalid_argument(std::string(kFunction) + ": shard_count " +
                                std::to_string(shard_count) + "; expected at least 1");
  }
  Json metadata;
  std::string problem = parse_json(metadata_json, &metadata);
  if (problem.empty() && !metadata.is_object())
    problem = "is " + describe(metadata);
  if (!problem.empty()) {
    throw std::invalid_argument(std::string(kFunction) + ": metadata_json " + problem +
                                "; expected the text of a JSON object, such as {\"seed\": 1}");
  }

  // every shard complete, in order
  Json shards = Json::array();
  std::int64_t rows = 0;
  for (int s = 0; s < shard_count; ++s) {
    ShardRecord record = read_complete_shard(dir, s, columns, dataset_id);
    record.dataset.clear();  // recorded once, at the top of the manifest
    if (record.rows > kMaxInt64 - rows)
      fail(marker_path(dir, s).string(),
           "the rows of shards 0.." + std::to_string(s) + " overflow 64 bits");
    rows += record.rows;
    shards.push_back(shard_json(record, columns));
  }

  Json column_array = Json::array();
  for (const ColumnSpec& c : columns) {
    column_array.push_back(
        {{"name", c.name}, {"dtype", dtype_name(c.dtype)}, {"row_shape", c.row_shape}});
  }
  const Json manifest = {{"format", kDatasetFormat},
                         {"format_version", kDatasetFormatVersion},
                         {"rows", rows},
                         {"columns", column_array},
                         {"shards", shards},
                         {"metadata", metadata}};
  Json out = manifest;
  if (!dataset_id.empty())
    out["dataset"] = dataset_id;
  const std::string text = out.dump(2) + "\n";
  write_text_file_atomically(dir / "manifest.json", text);
}

}  // namespace ropes::core
