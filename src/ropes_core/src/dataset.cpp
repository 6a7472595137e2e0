#include "ropes_core/dataset.hpp"

#include <fcntl.h>
#include <sys/resource.h>
#include <sys/stat.h>
#include <unistd.h>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cerrno>
#include <cstdio>
#include <cstring>
#include <limits>
#include <set>
#include <stdexcept>
#include <utility>

#include "ropes_core/file_io.hpp"
#include "ropes_core/json_text.hpp"
#include "ropes_core/philox.hpp"
#include "ropes_core/sha256.hpp"

namespace ropes::core {

namespace {

namespace fs = std::filesystem;
using Json = nlohmann::json;

constexpr std::uint64_t kMaxManifestBytes = std::uint64_t{64} << 20;
constexpr std::uint64_t kMaxMarkerBytes = std::uint64_t{1} << 20;
constexpr std::size_t kMaxColumnNameLength = 64;
constexpr std::size_t kVerifyChunkBytes = std::size_t{1} << 20;
constexpr std::int64_t kMaxInt64 = std::numeric_limits<std::int64_t>::max();

[[noreturn]] void fail(const std::string& name, const std::string& what) {
  throw FileFormatError(name + ": " + what);
}

// --- names and shapes ------------------------------------------------------------------------

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

// --- files -----------------------------------------------------------------------------------

// an open file descriptor, closed on destruction
class Fd {
 public:
  Fd() = default;
  explicit Fd(int fd) : fd_(fd) {}
  Fd(Fd&& other) noexcept : fd_(std::exchange(other.fd_, -1)) {}
  Fd& operator=(Fd&& other) noexcept {
    if (this != &other) {
      close();
      fd_ = std::exchange(other.fd_, -1);
    }
    return *this;
  }
  Fd(const Fd&) = delete;
  Fd& operator=(const Fd&) = delete;
  ~Fd() { close(); }
  int get() const { return fd_; }

 private:
  void close() {
    if (fd_ >= 0)
      ::close(fd_);
    fd_ = -1;
  }
  int fd_ = -1;
};

Fd open_file(const std::string& name, const std::string& context) {
  const int fd = ::open(name.c_str(), O_RDONLY | O_CLOEXEC);
  if (fd < 0) {
    const int error = errno;
    fail(name, context + "cannot open: " + std::strerror(error) +
                   (error == EMFILE ? " (a reader holds one descriptor per column per shard: "
                                      "raise `ulimit -n` or write fewer, larger shards)"
                                    : ""));
  }
  return Fd(fd);
}

std::uint64_t size_of(const Fd& fd, const std::string& name) {
  struct stat info {};
  if (::fstat(fd.get(), &info) != 0)
    fail(name, std::string("cannot stat: ") + std::strerror(errno));
  return static_cast<std::uint64_t>(info.st_size);
}

// exactly `n` bytes at `offset`, or a FileFormatError naming the file
void pread_all(int fd, void* out, std::size_t n, std::uint64_t offset, const std::string& name) {
  auto* p = static_cast<std::uint8_t*>(out);
  while (n > 0) {
    const ssize_t got = ::pread(fd, p, n, static_cast<off_t>(offset));
    if (got < 0 && errno == EINTR)
      continue;
    if (got < 0) {
      fail(name, "reading " + std::to_string(n) + " bytes at byte " + std::to_string(offset) +
                     " failed: " + std::strerror(errno));
    }
    if (got == 0) {
      fail(name, "ends at byte " + std::to_string(offset) + ", " + std::to_string(n) +
                     " bytes short (truncated after the dataset was opened?)");
    }
    p += got;
    n -= static_cast<std::size_t>(got);
    offset += static_cast<std::uint64_t>(got);
  }
}

// the .npy header of an open file of `size` bytes: only the header's bytes are read
NpyHeader read_header(const Fd& fd, std::uint64_t size, const std::string& name) {
  // magic (6), version (2), then a 2-byte (1.0) or 4-byte (2.0, 3.0) length
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(std::min<std::uint64_t>(size, 12)));
  pread_all(fd.get(), bytes.data(), bytes.size(), 0, name);
  std::uint64_t want = bytes.size();
  if (bytes.size() == 12) {
    const bool v1 = bytes[6] == 1;
    std::uint64_t length = 0;
    for (int i = 0; i < (v1 ? 2 : 4); ++i)
      length |= static_cast<std::uint64_t>(bytes[8 + i]) << (8 * i);
    // a length over the limit is refused by the parser from the prefix alone
    if (length <= kNpyMaxHeaderBytes)
      want = std::min<std::uint64_t>(size, (v1 ? 10 : 12) + length);
  }
  if (want > bytes.size()) {
    bytes.resize(static_cast<std::size_t>(want));
    pread_all(fd.get(), bytes.data(), bytes.size(), 0, name);
  }
  return parse_npy_header(bytes.data(), bytes.size(), name);
}

// checks an open column file against its column, rows and recorded size; returns its header
NpyHeader check_column_file(const Fd& fd, const std::string& name, const ColumnSpec& column,
                            std::int64_t rows, std::uint64_t recorded_bytes,
                            const std::string& context) {
  const std::uint64_t size = size_of(fd, name);
  NpyHeader header = read_header(fd, size, name);
  if (header.dtype != column.dtype) {
    fail(name, context + "dtype is " + dtype_name(header.dtype) + "; column '" + column.name +
                   "' expects " + dtype_name(column.dtype));
  }
  const std::vector<std::int64_t> expected = file_shape(rows, column.row_shape);
  if (header.shape != expected) {
    fail(name, context + "shape is " + shape_text(header.shape) + "; column '" + column.name +
                   "' expects [rows, row_shape...] = " + shape_text(expected));
  }
  if (size != header.data_offset + header.data_bytes) {
    fail(name, context + "holds " + std::to_string(size) + " bytes; its header needs " +
                   std::to_string(header.data_offset + header.data_bytes) + " (truncated?)");
  }
  if (size != recorded_bytes) {
    fail(name, context + "holds " + std::to_string(size) + " bytes; the record says " +
                   std::to_string(recorded_bytes));
  }
  return header;
}

// --- JSON ------------------------------------------------------------------------------------

// the descriptors this process holds open now (those listed in /proc/self/fd, less the one
// that lists them); 0 when that cannot be read
std::uint64_t count_open_descriptors() {
  std::error_code ec;
  std::uint64_t n = 0;
  for (fs::directory_iterator it("/proc/self/fd", ec), end; !ec && it != end; it.increment(ec))
    ++n;
  return n > 0 ? n - 1 : 0;
}

// the text of a small file; a FileFormatError naming it when missing, too large or unreadable
std::string read_text_file(const fs::path& path, std::uint64_t max_bytes,
                           const std::string& context) {
  const std::string name = path.string();
  const Fd fd = open_file(name, context);
  const std::uint64_t size = size_of(fd, name);
  if (size > max_bytes) {
    fail(name, context + "holds " + std::to_string(size) + " bytes; expected at most " +
                   std::to_string(max_bytes));
  }
  std::string text(static_cast<std::size_t>(size), '\0');
  pread_all(fd.get(), text.data(), text.size(), 0, name);
  return text;
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
  const std::string problem = parse_json(read_text_file(marker, kMaxMarkerBytes, context), &json);
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

// the bounded draw of shuffled_indices: uniform on [0, bound), by rejection
std::uint64_t uniform_below(PhiloxStream& rng, std::uint64_t bound) {
  if (bound <= 0xffffffffull) {
    const auto b = static_cast<std::uint32_t>(bound);
    const std::uint32_t threshold = static_cast<std::uint32_t>(-b) % b;  // 2^32 mod bound
    while (true) {
      const std::uint32_t w = rng.next_u32();
      if (w >= threshold)
        return w % b;
    }
  }
  const std::uint64_t threshold = (0 - bound) % bound;  // 2^64 mod bound
  while (true) {
    const std::uint64_t low = rng.next_u32();
    const std::uint64_t w = low | static_cast<std::uint64_t>(rng.next_u32()) << 32;
    if (w >= threshold)
      return w % bound;
  }
}

}  // namespace

// --- writing ---------------------------------------------------------------------------------

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
  write_file_atomically(marker, reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
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
  write_file_atomically(dir / "manifest.json", reinterpret_cast<const std::uint8_t*>(text.data()),
                        text.size());
}

// --- reading ---------------------------------------------------------------------------------

struct DatasetReader::State {
  struct File {
    std::string name;  // full path, for messages
    Fd fd;
    std::uint64_t data_offset = 0;
    std::uint64_t bytes = 0;
    std::string sha256;
  };

  fs::path dir;
  std::int64_t rows = 0;
  std::vector<ColumnSpec> columns;
  std::vector<std::uint64_t> row_bytes;   // per column
  std::string metadata;                   // compact JSON
  Json metadata_value;                    // the same, parsed
  std::vector<std::int64_t> shard_first;  // first row of each shard, then rows
  std::vector<File> files;                // [shard * columns.size() + column]

  std::size_t column_index(const std::string& name) const {
    for (std::size_t i = 0; i < columns.size(); ++i) {
      if (columns[i].name == name)
        return i;
    }
    throw std::out_of_range("DatasetReader: no column '" + name + "' in " + dir.string() +
                            "; it has " + column_list(columns));
  }
};

DatasetReader::DatasetReader(std::unique_ptr<State> state) : state_(std::move(state)) {}
DatasetReader::DatasetReader(DatasetReader&&) noexcept = default;
DatasetReader& DatasetReader::operator=(DatasetReader&&) noexcept = default;
DatasetReader::~DatasetReader() = default;

DatasetReader DatasetReader::open(const fs::path& dir) {
  auto state = std::make_unique<State>();
  state->dir = dir;

  // the manifest: present, bounded, JSON, our format and version
  const fs::path manifest_path = dir / "manifest.json";
  const std::string name = manifest_path.string();
  std::error_code ec;
  if (!fs::exists(manifest_path, ec)) {
    fail(dir.string(), "holds no complete dataset (" + name +
                           " missing; write_dataset_manifest writes it once every shard is "
                           "complete)");
  }
  Json manifest;
  const std::string problem =
      parse_json(read_text_file(manifest_path, kMaxManifestBytes, ""), &manifest);
  if (!problem.empty())
    fail(name, problem);
  if (!manifest.is_object())
    fail(name, "is " + describe(manifest) + "; expected a JSON object");
  const Json& format = member(manifest, "format", name, "");
  if (format != kDatasetFormat)
    fail(name, "format is " + describe(format) + "; expected \"" + kDatasetFormat + "\"");
  const Json& version = member(manifest, "format_version", name, "");
  if (!version.is_number_unsigned() ||
      version.get<std::uint64_t>() != static_cast<std::uint64_t>(kDatasetFormatVersion)) {
    fail(name, "format_version is " + describe(version) + "; expected " +
                   std::to_string(kDatasetFormatVersion) + " (the only version this reader knows)");
  }

  // columns
  const Json& columns = member(manifest, "columns", name, "");
  if (!columns.is_array() || columns.empty())
    fail(name, "columns is " + describe(columns) + "; expected a non-empty array");
  std::set<std::string> names;
  for (std::size_t i = 0; i < columns.size(); ++i) {
    const std::string field = "columns[" + std::to_string(i) + "]";
    const Json& c = columns[i];
    ColumnSpec spec;
    const Json& column_name = member(c, "name", name, field);
    const std::string name_problem =
        column_name.is_string() ? column_name_problem(column_name.get<std::string>()) : "?";
    if (!name_problem.empty() || !names.insert(column_name.get<std::string>()).second) {
      fail(name, field + ".name is " + describe(column_name) +
                     "; expected a distinct name of letters, digits, _ - .");
    }
    spec.name = column_name.get<std::string>();
    const Json& dtype = member(c, "dtype", name, field);
    if (!dtype.is_string() || !parse_dtype(dtype.get<std::string>(), &spec.dtype))
      fail(name, field + ".dtype is " + describe(dtype) + "; expected u8, i32, i64, f32 or f64");
    const Json& row_shape = member(c, "row_shape", name, field);
    if (!row_shape.is_array() || row_shape.size() + 1 > static_cast<std::size_t>(kNpyMaxRank)) {
      fail(name, field + ".row_shape is " + describe(row_shape) +
                     "; expected an array of at most " + std::to_string(kNpyMaxRank - 1) +
                     " sizes");
    }
    for (std::size_t d = 0; d < row_shape.size(); ++d) {
      spec.row_shape.push_back(
          count_value(row_shape[d], name, field + ".row_shape[" + std::to_string(d) + "]"));
    }
    std::uint64_t bytes = 0;
    if (!checked_byte_count(spec.dtype, spec.row_shape, &bytes))
      fail(name, field + ".row_shape " + shape_text(spec.row_shape) + " overflows 64 bits");
    state->row_bytes.push_back(bytes);
    state->columns.push_back(std::move(spec));
  }

  // shards, whose rows must add up to the total
  const Json& shards = member(manifest, "shards", name, "");
  if (!shards.is_array() || shards.empty() ||
      shards.size() > static_cast<std::size_t>(std::numeric_limits<int>::max())) {
    fail(name, "shards is " + describe(shards) + "; expected a non-empty array");
  }
  std::vector<ShardRecord> records;
  std::int64_t sum = 0;
  for (std::size_t s = 0; s < shards.size(); ++s) {
    records.push_back(parse_shard(shards[s], state->columns, static_cast<int>(s), name,
                                  "shards[" + std::to_string(s) + "]"));
    if (records.back().rows > kMaxInt64 - sum)
      fail(name, "the shards' rows overflow 64 bits");
    state->shard_first.push_back(sum);
    sum += records.back().rows;
  }
  state->shard_first.push_back(sum);
  state->rows = count_value(member(manifest, "rows", name, ""), name, "rows");
  if (state->rows != sum) {
    fail(name,
         "rows is " + std::to_string(state->rows) + "; the shards hold " + std::to_string(sum));
  }
  const Json& metadata = member(manifest, "metadata", name, "");
  if (!metadata.is_object())
    fail(name, "metadata is " + describe(metadata) + "; expected an object");
  state->metadata = metadata.dump();
  state->metadata_value = metadata;

  // every file open, its header and size as the manifest says; first, that the descriptors
  // fit under the process's limit with room to spare (a reader holds one per file)
  const std::uint64_t files = records.size() * state->columns.size();
  rlimit limit{};
  if (::getrlimit(RLIMIT_NOFILE, &limit) == 0 && limit.rlim_cur != RLIM_INFINITY) {
    const std::uint64_t open_now = count_open_descriptors();
    const std::uint64_t spare = 64;
    if (open_now + files + spare > limit.rlim_cur) {
      fail(name, "lists " + std::to_string(records.size()) + " shards of " +
                     std::to_string(state->columns.size()) + " columns: " + std::to_string(files) +
                     " files to hold open, with " + std::to_string(open_now) +
                     " open already and " + std::to_string(spare) +
                     " to spare, over this process's limit of " + std::to_string(limit.rlim_cur) +
                     " file descriptors (raise it with ulimit -n, or write fewer, larger shards)");
    }
  }
  for (std::size_t s = 0; s < records.size(); ++s) {
    for (std::size_t c = 0; c < state->columns.size(); ++c) {
      const FileRecord& record = records[s].files[c];
      State::File file;
      file.name = (dir / record.path).string();
      file.fd = open_file(file.name, "");
      file.data_offset = check_column_file(file.fd, file.name, state->columns[c], records[s].rows,
                                           record.bytes, "")
                             .data_offset;
      file.bytes = record.bytes;
      file.sha256 = record.sha256;
      state->files.push_back(std::move(file));
    }
  }
  return DatasetReader(std::move(state));
}

const fs::path& DatasetReader::dir() const {
  return state_->dir;
}
std::int64_t DatasetReader::rows() const {
  return state_->rows;
}
int DatasetReader::shard_count() const {
  return static_cast<int>(state_->shard_first.size()) - 1;
}
const std::vector<ColumnSpec>& DatasetReader::columns() const {
  return state_->columns;
}
const ColumnSpec& DatasetReader::column(const std::string& name) const {
  return state_->columns[state_->column_index(name)];
}
const std::string& DatasetReader::metadata_json() const {
  return state_->metadata;
}

const Json& DatasetReader::metadata() const {
  return state_->metadata_value;
}

const Json& DatasetReader::metadata_at(const std::string& json_pointer,
                                       const std::string& hint) const {
  Json::json_pointer pointer;
  try {
    pointer = Json::json_pointer(json_pointer);
  } catch (const Json::exception& e) {
    throw std::invalid_argument(
        "DatasetReader::metadata_at: '" + json_pointer +
        "' is not a JSON pointer (RFC 6901, such as \"/regimes/0\"): " + e.what());
  }
  const Json& metadata = state_->metadata_value;
  if (!metadata.contains(pointer)) {
    fail((state_->dir / "manifest.json").string(),
         "metadata has no " + json_pointer + (hint.empty() ? "" : " (" + hint + ")"));
  }
  return metadata.at(pointer);
}

void DatasetReader::read_rows(const std::string& column, std::int64_t first, std::int64_t count,
                              void* out) const {
  const State& st = *state_;
  const std::size_t c = st.column_index(column);
  if (first < 0 || count < 0 || first > st.rows - count) {
    const std::string range =
        first >= 0 && count >= 0
            ? "[" + std::to_string(first) + ", " +
                  std::to_string(static_cast<std::uint64_t>(first) +
                                 static_cast<std::uint64_t>(count)) +
                  ")"
            : "from " + std::to_string(first) + ", count " + std::to_string(count);
    throw std::out_of_range("DatasetReader::read_rows: rows " + range + " of column '" + column +
                            "' lie outside the dataset's " + std::to_string(st.rows) + " rows (" +
                            st.dir.string() + ")");
  }
  const std::uint64_t row_bytes = st.row_bytes[c];
  auto* dst = static_cast<std::uint8_t*>(out);
  // the shard holding `first`, then on through the following ones
  std::size_t s = static_cast<std::size_t>(
      std::upper_bound(st.shard_first.begin(), st.shard_first.end(), first) -
      st.shard_first.begin() - 1);
  while (count > 0) {
    const std::int64_t n = std::min(count, st.shard_first[s + 1] - first);
    const State::File& file = st.files[s * st.columns.size() + c];
    const auto local = static_cast<std::uint64_t>(first - st.shard_first[s]);
    const std::uint64_t bytes = static_cast<std::uint64_t>(n) * row_bytes;
    pread_all(file.fd.get(), dst, static_cast<std::size_t>(bytes),
              file.data_offset + local * row_bytes, file.name);
    dst += bytes;
    first += n;
    count -= n;
    ++s;
  }
}

NpyArray DatasetReader::read_rows(const std::string& column, std::int64_t first,
                                  std::int64_t count) const {
  const std::size_t c = state_->column_index(column);
  NpyArray array;
  array.dtype = state_->columns[c].dtype;
  array.shape = file_shape(std::max<std::int64_t>(count, 0), state_->columns[c].row_shape);
  // a valid range is bounded by the files' sizes; an invalid one throws before reading
  if (first >= 0 && count >= 0 && first <= state_->rows - count)
    array.data.resize(static_cast<std::size_t>(count) * state_->row_bytes[c]);
  read_rows(column, first, count, array.data.data());
  return array;
}

void DatasetReader::read_rows_at(const std::string& column, const std::vector<std::int64_t>& rows,
                                 void* out) const {
  const State& st = *state_;
  const std::size_t c = st.column_index(column);
  for (std::size_t i = 0; i < rows.size(); ++i) {
    if (rows[i] < 0 || rows[i] >= st.rows) {
      throw std::out_of_range("DatasetReader::read_rows_at: rows[" + std::to_string(i) +
                              "] = " + std::to_string(rows[i]) + " of column '" + column +
                              "' lies outside the dataset's " + std::to_string(st.rows) +
                              " rows (" + st.dir.string() + ")");
    }
  }
  // runs of consecutive rows, each one read_rows
  auto* dst = static_cast<std::uint8_t*>(out);
  const std::uint64_t row_bytes = st.row_bytes[c];
  for (std::size_t i = 0; i < rows.size();) {
    std::size_t j = i + 1;
    while (j < rows.size() && rows[j] == rows[j - 1] + 1)
      ++j;
    const auto count = static_cast<std::int64_t>(j - i);
    read_rows(column, rows[i], count, dst);
    dst += static_cast<std::uint64_t>(count) * row_bytes;
    i = j;
  }
}

NpyArray DatasetReader::read_rows_at(const std::string& column,
                                     const std::vector<std::int64_t>& rows) const {
  const std::size_t c = state_->column_index(column);
  NpyArray array;
  array.dtype = state_->columns[c].dtype;
  array.shape = file_shape(static_cast<std::int64_t>(rows.size()), state_->columns[c].row_shape);
  array.data.resize(rows.size() * state_->row_bytes[c]);
  read_rows_at(column, rows, array.data.data());
  return array;
}

void DatasetReader::verify() const {
  std::vector<std::uint8_t> chunk(kVerifyChunkBytes);
  for (const State::File& file : state_->files) {
    Sha256 hash;
    for (std::uint64_t offset = 0; offset < file.bytes; offset += chunk.size()) {
      const auto n =
          static_cast<std::size_t>(std::min<std::uint64_t>(chunk.size(), file.bytes - offset));
      pread_all(file.fd.get(), chunk.data(), n, offset, file.name);
      hash.update(chunk.data(), n);
    }
    const std::string actual = sha256_hex(hash.finish());
    if (actual != file.sha256) {
      fail(file.name, "sha256 is " + actual + "; the manifest records " + file.sha256 +
                          " (the file changed after it was written)");
    }
  }
}

// --- batching --------------------------------------------------------------------------------

std::vector<std::int64_t> shuffled_indices(std::int64_t n, std::uint64_t seed,
                                           std::uint64_t epoch) {
  if (n < 0) {
    throw std::invalid_argument("shuffled_indices: n = " + std::to_string(n) + "; expected n >= 0");
  }
  std::vector<std::int64_t> order(static_cast<std::size_t>(n));
  for (std::int64_t i = 0; i < n; ++i)
    order[static_cast<std::size_t>(i)] = i;
  // Fisher-Yates from the back
  PhiloxStream rng(seed, kShuffleStreamBase + epoch);
  for (std::int64_t i = n - 1; i > 0; --i) {
    const std::uint64_t j = uniform_below(rng, static_cast<std::uint64_t>(i) + 1);
    std::swap(order[static_cast<std::size_t>(i)], order[static_cast<std::size_t>(j)]);
  }
  return order;
}

}  // namespace ropes::core
