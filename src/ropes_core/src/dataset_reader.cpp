// The dataset container's reader: DatasetReader.
#include "ropes_core/dataset.hpp"

#include <sys/mman.h>
#include <sys/resource.h>

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
      parse_json(read_small_file(manifest_path, kMaxManifestBytes, ""), &manifest);
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
std::int64_t DatasetReader::shard_rows(int shard) const {
  if (shard < 0 || shard >= shard_count()) {
    throw std::out_of_range("DatasetReader: no shard " + std::to_string(shard) + " in " +
                            state_->dir.string() + "; it has " + std::to_string(shard_count()));
  }
  return state_->shard_first[static_cast<std::size_t>(shard) + 1] -
         state_->shard_first[static_cast<std::size_t>(shard)];
}

DatasetReader::MappedRows DatasetReader::map_shard(const std::string& column, int shard) const {
  const std::size_t c = state_->column_index(column);
  const std::int64_t rows = shard_rows(shard);
  const State::File& f =
      state_->files[static_cast<std::size_t>(shard) * state_->columns.size() + c];
  const std::size_t length = static_cast<std::size_t>(f.data_offset + f.bytes);
  void* base = ::mmap(nullptr, length, PROT_READ, MAP_SHARED, f.fd.get(), 0);
  if (base == MAP_FAILED)
    fail(f.name, std::string("cannot be memory-mapped: ") + std::strerror(errno));
  MappedRows m;
  m.mapping = std::shared_ptr<const void>(
      base, [length](const void* p) { ::munmap(const_cast<void*>(p), length); });
  m.data = static_cast<const std::uint8_t*>(base) + f.data_offset;
  m.dtype = state_->columns[c].dtype;
  m.shape = {rows};
  m.shape.insert(m.shape.end(), state_->columns[c].row_shape.begin(),
                 state_->columns[c].row_shape.end());
  return m;
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

}  // namespace ropes::core
