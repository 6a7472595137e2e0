#include "dataset_layout.hpp"

#include <algorithm>
#include <cstdio>
#include <set>
#include <stdexcept>

#include "dataset_files.hpp"
#include "ropes_core/file_format_error.hpp"
#include "ropes_core/json_text.hpp"
#include "ropes_core/npy.hpp"

namespace ropes::core::detail {

std::string shard_stem(int shard) {
  char text[16];
  std::snprintf(text, sizeof(text), "%05d", shard);
  return text;
}

// a column file's path relative to the dataset directory, as markers and the manifest record it
std::string column_file(const std::string& column, int shard) {
  return "shards/" + column + "-" + shard_stem(shard) + ".npy";
}

fs::path marker_path(const fs::path& dir, int shard) {
  return dir / "shards" / (shard_stem(shard) + ".json");
}

std::string shape_text(const std::vector<std::int64_t>& shape) {
  std::string out = "[";
  for (std::size_t i = 0; i < shape.size(); ++i)
    out += (i ? ", " : "") + std::to_string(shape[i]);
  return out + "]";
}

std::vector<std::int64_t> file_shape(std::int64_t rows,
                                     const std::vector<std::int64_t>& row_shape) {
  std::vector<std::int64_t> shape = {rows};
  shape.insert(shape.end(), row_shape.begin(), row_shape.end());
  return shape;
}

std::string column_list(const std::vector<ColumnSpec>& columns) {
  std::string out;
  for (const ColumnSpec& c : columns)
    out += (out.empty() ? "" : ", ") + c.name;
  return out;
}

bool parse_dtype(const std::string& text, DType* out) {
  for (DType d : {DType::kU8, DType::kI32, DType::kI64, DType::kF32, DType::kF64}) {
    if (text == dtype_name(d)) {
      *out = d;
      return true;
    }
  }
  return false;
}

// what is wrong with a column name, or "" when nothing is
std::string column_name_problem(const std::string& name) {
  if (name.empty() || name.size() > kMaxColumnNameLength) {
    return "has " + std::to_string(name.size()) + " characters; expected 1 to " +
           std::to_string(kMaxColumnNameLength);
  }
  for (char c : name) {
    const bool ok = (c >= 'a' && c <= 'z') || (c >= 'A' && c <= 'Z') || (c >= '0' && c <= '9') ||
                    c == '_' || c == '-' || c == '.';
    if (!ok)
      return "holds the character '" + std::string(1, c) + "'; expected letters, digits, _ - .";
  }
  if (name[0] == '.' || name[0] == '-')
    return "starts with '" + std::string(1, name[0]) + "'; expected a letter, digit or _";
  return "";
}

// std::invalid_argument for column specs a caller got wrong
void check_columns(const char* function, const std::vector<ColumnSpec>& columns) {
  if (columns.empty())
    throw std::invalid_argument(std::string(function) + ": no columns; expected at least one");
  std::set<std::string> names;
  for (const ColumnSpec& c : columns) {
    const std::string problem = column_name_problem(c.name);
    if (!problem.empty()) {
      throw std::invalid_argument(std::string(function) + ": column name '" + c.name + "' " +
                                  problem);
    }
    if (!names.insert(c.name).second) {
      throw std::invalid_argument(std::string(function) + ": column '" + c.name +
                                  "' appears twice; expected distinct names");
    }
    std::uint64_t bytes = 0;
    if (c.row_shape.size() + 1 > static_cast<std::size_t>(kNpyMaxRank) ||
        !checked_byte_count(c.dtype, c.row_shape, &bytes)) {
      throw std::invalid_argument(std::string(function) + ": column '" + c.name +
                                  "' has row_shape " + shape_text(c.row_shape) +
                                  "; expected at most " + std::to_string(kNpyMaxRank - 1) +
                                  " non-negative sizes whose byte count fits 64 bits");
    }
  }
}

void check_shard_number(const char* function, int shard) {
  if (shard < 0) {
    throw std::invalid_argument(std::string(function) + ": shard " + std::to_string(shard) +
                                "; expected a shard number >= 0");
  }
}

const Json& member(const Json& object, const char* key, const std::string& name,
                   const std::string& where) {
  if (!object.is_object() || !object.contains(key)) {
    fail(name, where + (where.empty() ? "" : " ") + "lacks \"" + key + "\"");
  }
  return object[key];
}

// a non-negative integer that fits int64
std::int64_t count_value(const Json& v, const std::string& name, const std::string& field) {
  if (!v.is_number_unsigned() || v.get<std::uint64_t>() > static_cast<std::uint64_t>(kMaxInt64))
    fail(name, field + " is " + describe(v) + "; expected a non-negative integer");
  return static_cast<std::int64_t>(v.get<std::uint64_t>());
}

bool is_sha256_hex(const Json& v) {
  if (!v.is_string())
    return false;
  const std::string& s = v.get_ref<const std::string&>();
  return s.size() == 64 && std::all_of(s.begin(), s.end(), [](char c) {
           return (c >= '0' && c <= '9') || (c >= 'a' && c <= 'f');
         });
}

// {"files": {column: {"bytes", "path", "sha256"}}, "rows"}: a marker, or a manifest's shard
Json shard_json(const ShardRecord& record, const std::vector<ColumnSpec>& columns) {
  Json files = Json::object();
  for (std::size_t i = 0; i < columns.size(); ++i) {
    const FileRecord& f = record.files[i];
    files[columns[i].name] = {{"path", f.path}, {"bytes", f.bytes}, {"sha256", f.sha256}};
  }
  Json out = {{"rows", record.rows}, {"files", files}};
  if (!record.dataset.empty())
    out["dataset"] = record.dataset;
  return out;
}

// a recorded file path, which must be the canonical one (never "../" or an absolute path)
std::string canonical_path(const Json& path, const std::string& column, int shard,
                           const std::string& name, const std::string& field) {
  std::string expected = column_file(column, shard);
  if (!path.is_string() || path.get_ref<const std::string&>() != expected)
    fail(name, field + ".path is " + describe(path) + "; expected \"" + expected + "\"");
  return expected;
}

// parses a marker or a manifest's shard entry; `where` prefixes field names in messages
ShardRecord parse_shard(const Json& v, const std::vector<ColumnSpec>& columns, int shard,
                        const std::string& name, const std::string& where) {
  if (!v.is_object())
    fail(name, where + " is " + describe(v) + "; expected an object with rows and files");
  ShardRecord record;
  record.rows = count_value(member(v, "rows", name, where), name, where + ".rows");
  if (v.contains("dataset")) {
    const Json& id = v["dataset"];
    if (!id.is_string() || id.get_ref<const std::string&>().empty())
      fail(name, where + ".dataset is " + describe(id) + "; expected a non-empty string");
    record.dataset = id.get<std::string>();
  }
  if (record.rows == 0)
    fail(name, where + ".rows is 0; expected at least 1");
  const Json& files = member(v, "files", name, where);
  if (!files.is_object() || files.size() != columns.size()) {
    fail(name, where + ".files is " + describe(files) + " of " + std::to_string(files.size()) +
                   " entries; expected one per column (" + column_list(columns) + ")");
  }
  for (const ColumnSpec& column : columns) {
    const std::string field = where + ".files." + column.name;
    const Json& entry = member(files, column.name.c_str(), name, where + ".files");
    FileRecord f;
    f.path = canonical_path(member(entry, "path", name, field), column.name, shard, name, field);
    f.bytes = static_cast<std::uint64_t>(
        count_value(member(entry, "bytes", name, field), name, field + ".bytes"));
    const Json& hash = member(entry, "sha256", name, field);
    if (!is_sha256_hex(hash)) {
      fail(name,
           field + ".sha256 is " + describe(hash) + "; expected 64 lower-case hexadecimal digits");
    }
    f.sha256 = hash.get<std::string>();
    record.files.push_back(std::move(f));
  }
  return record;
}

// shard `shard`'s marker, checked against its files; FileFormatError when it is not complete
ShardRecord read_complete_shard(const fs::path& dir, int shard,
                                const std::vector<ColumnSpec>& columns,
                                const std::string& dataset_id) {
  const std::string context = "shard " + std::to_string(shard) + " is not complete: ";
  const fs::path marker = marker_path(dir, shard);
  const std::string name = marker.string();
  Json json;
  const std::string problem = parse_json(read_small_file(marker, kMaxMarkerBytes, context), &json);
  if (!problem.empty())
    fail(name, context + "the marker " + problem);
  ShardRecord record = parse_shard(json, columns, shard, name, context + "marker");
  if (record.dataset != dataset_id) {
    fail(name, context + "the marker's dataset is \"" + record.dataset + "\"; expected \"" +
                   dataset_id + "\" (a shard of another dataset)");
  }
  for (std::size_t i = 0; i < columns.size(); ++i) {
    const std::string file = (dir / record.files[i].path).string();
    check_column_file(open_file(file, context), file, columns[i], record.rows,
                      record.files[i].bytes, context);
  }
  return record;
}

}  // namespace ropes::core::detail
