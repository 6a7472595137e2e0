#pragma once
// The dataset container's layout on disk (private to ropes_core; dataset.hpp is the API): the
// limits, the names of shard and marker files, the checks of column specs, and the records of a
// shard (its marker, a manifest's entry) with their parsers.
#include <nlohmann/json.hpp>

#include <cstddef>
#include <cstdint>
#include <filesystem>
#include <limits>
#include <string>
#include <vector>

#include "file_errors.hpp"
#include "ropes_core/dataset.hpp"

namespace ropes::core::detail {

namespace fs = std::filesystem;
using Json = nlohmann::json;

inline constexpr std::uint64_t kMaxMarkerBytes = std::uint64_t{1} << 20;
inline constexpr std::size_t kMaxColumnNameLength = 64;
inline constexpr std::size_t kVerifyChunkBytes = std::size_t{1} << 20;
inline constexpr std::int64_t kMaxInt64 = std::numeric_limits<std::int64_t>::max();

std::string shard_stem(int shard);

// a column file's path relative to the dataset directory, as markers and the manifest record it
std::string column_file(const std::string& column, int shard);

fs::path marker_path(const fs::path& dir, int shard);

std::string shape_text(const std::vector<std::int64_t>& shape);

std::vector<std::int64_t> file_shape(std::int64_t rows, const std::vector<std::int64_t>& row_shape);

std::string column_list(const std::vector<ColumnSpec>& columns);

bool parse_dtype(const std::string& text, DType* out);

// what is wrong with a column name, or "" when nothing is
std::string column_name_problem(const std::string& name);

// std::invalid_argument for column specs a caller got wrong
void check_columns(const char* function, const std::vector<ColumnSpec>& columns);

void check_shard_number(const char* function, int shard);

const Json& member(const Json& object, const char* key, const std::string& name,
                   const std::string& where);

// a non-negative integer that fits int64
std::int64_t count_value(const Json& v, const std::string& name, const std::string& field);

bool is_sha256_hex(const Json& v);

struct FileRecord {
  std::string path;  // relative to the dataset directory
  std::uint64_t bytes = 0;
  std::string sha256;
};

struct ShardRecord {
  std::int64_t rows = 0;
  std::string dataset;            // the writer's dataset id; empty when none was given
  std::vector<FileRecord> files;  // in column order
};

// {"files": {column: {"bytes", "path", "sha256"}}, "rows"}: a marker, or a manifest's shard
Json shard_json(const ShardRecord& record, const std::vector<ColumnSpec>& columns);

// a recorded file path, which must be the canonical one (never "../" or an absolute path)
std::string canonical_path(const Json& path, const std::string& column, int shard,
                           const std::string& name, const std::string& field);

// parses a marker or a manifest's shard entry; `where` prefixes field names in messages
ShardRecord parse_shard(const Json& v, const std::vector<ColumnSpec>& columns, int shard,
                        const std::string& name, const std::string& where);

// shard `shard`'s marker, checked against its files; FileFormatError when it is not complete
ShardRecord read_complete_shard(const fs::path& dir, int shard,
                                const std::vector<ColumnSpec>& columns,
                                const std::string& dataset_id);

}  // namespace ropes::core::detail
