#pragma once
/// @file dataset.hpp
/// The generic dataset container: named columns of rows, stored as one .npy file per column
/// per shard, with a JSON manifest that records every file's size and SHA-256. It knows no
/// robot: the writer decides the columns (say images u8 [n, cams, H, W], angles f32 [n, 7])
/// and the free-form metadata; readers find them by name.
///
/// Layout of a dataset directory DIR:
///   DIR/shards/<column>-<shard:05d>.npy  dim 0 = the shard's rows, then the column's row shape
///   DIR/shards/<shard:05d>.json          the shard's marker, written after its column files:
///       {"files": {column: {"bytes": B, "path": "shards/<column>-<shard:05d>.npy",
///                           "sha256": hex}}, "rows": n, "dataset": id (when given)}
///   DIR/manifest.json                    written last:
///       {"columns": [{"dtype": "f32", "name": ..., "row_shape": [...]}, ...],
///        "format": "ropes-dataset", "format_version": 1, "metadata": {caller's object},
///        "rows": N, "shards": [{"files": {...as in the marker...}, "rows": n}, ...]}
/// A shard is complete iff its marker parses and names exactly the columns, each file at
/// its canonical path, holding the recorded bytes and a .npy header of the column's dtype
/// and shape [rows, row_shape...]. The dataset is complete iff manifest.json exists. Every
/// file goes through write_file_atomically (temporary name + rename), so after a crash a
/// shard is complete or not, never half-written: a generator resumes by rewriting the
/// shards that dataset_shard_complete() refuses, then writes the manifest.
///
/// The JSON is dumped with sorted keys, indent 2 and a trailing newline, and the .npy files
/// are byte-identical to numpy's, so the same inputs give the same bytes everywhere.

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

#include <nlohmann/json_fwd.hpp>

#include "ropes_core/file_io.hpp"
#include "ropes_core/npy.hpp"

namespace ropes::core {

/// One column: its name (letters, digits, '_', '-', '.'; not starting with '.' or '-'; at
/// most 64 characters — it becomes part of file names), its element type and the shape of
/// one row (empty for a scalar per row, such as a label).
struct ColumnSpec {
  std::string name;
  DType dtype = DType::kF32;
  std::vector<std::int64_t> row_shape;

  bool operator==(const ColumnSpec& other) const {
    return name == other.name && dtype == other.dtype && row_shape == other.row_shape;
  }
  bool operator!=(const ColumnSpec& other) const { return !(*this == other); }
};

/// The container's format name and version, as the manifest records them.
inline constexpr const char* kDatasetFormat = "ropes-dataset";
inline constexpr int kDatasetFormatVersion = 1;
/// The largest manifest.json a reader accepts (DatasetReader::open refuses a larger one).
inline constexpr std::uint64_t kMaxManifestBytes = std::uint64_t{64} << 20;

/// Writes shard `shard` (>= 0) of the dataset in `dir`: `data[i]` is column `columns[i]`,
/// of dtype columns[i].dtype and shape [rows, columns[i].row_shape...], with the same
/// rows > 0 in every column. Creates DIR/shards, removes the shard's old marker (so a crash
/// while rewriting leaves it incomplete), writes each column file, then the marker.
/// Throws std::invalid_argument naming the column, the value found and the one expected for
/// a bad column spec (name, negative dimension, duplicate), a count of arrays other than
/// the columns', another dtype or shape, rows that differ or are 0, or data bytes that do
/// not match the shape; nothing is written then. Throws FileFormatError naming the file
/// when a file cannot be written, or DIR/shards when it is a symbolic link (the shards
/// are written only inside DIR). Cost: one SHA-256 pass over the data, plus the writes.
///
/// `dataset_id` (optional) names the dataset the shard belongs to (a writer passes, say, a
/// hash of its configuration); it is recorded in the marker as "dataset", and
/// dataset_shard_complete / write_dataset_manifest given an id accept only shards with that
/// id, so that shards of two datasets copied into one directory are never mixed.
void write_dataset_shard(const std::filesystem::path& dir, int shard,
                         const std::vector<ColumnSpec>& columns, const std::vector<NpyArray>& data,
                         const std::string& dataset_id = "");

/// True iff shard `shard` of `dir` is complete (see the file comment) for `columns`; false,
/// not an exception, when the marker is missing, unreadable or malformed, a file is missing
/// or has another size, or a header disagrees with a column. Reads the marker and each
/// file's .npy header, not the data (no hashing). Throws std::invalid_argument only for bad
/// column specs or shard < 0, as write_dataset_shard.
/// With a `dataset_id`, a marker with another (or no) id is not complete either.
bool dataset_shard_complete(const std::filesystem::path& dir, int shard,
                            const std::vector<ColumnSpec>& columns,
                            const std::string& dataset_id = "");

/// Why shard `shard` of `dir` is not complete, as the message of the FileFormatError that
/// names the file to blame; empty when it is complete (dataset_shard_complete). With
/// `check_sha256`, a complete shard whose files do not hash to its marker's SHA-256s (a
/// file damaged after writing) is not complete either. Throws as dataset_shard_complete.
/// Cost: with check_sha256, one SHA-256 pass over the shard's files.
std::string dataset_shard_problem(const std::filesystem::path& dir, int shard,
                                  const std::vector<ColumnSpec>& columns,
                                  const std::string& dataset_id = "", bool check_sha256 = false);

/// Writes DIR/manifest.json for shards 0 .. shard_count - 1, from their markers.
/// `metadata_json` must be the text of a JSON object (it is stored parsed, so formatting
/// does not matter). Throws std::invalid_argument for bad column specs, shard_count < 1 or
/// metadata that is not a JSON object; FileFormatError naming the marker of the first
/// shard that is not complete, and why; FileFormatError naming manifest.json when it
/// cannot be written. Same columns, markers and metadata give the same bytes.
/// With a `dataset_id`, every marker must carry it (FileFormatError naming the shard
/// otherwise) and the manifest records it once, as "dataset".
void write_dataset_manifest(const std::filesystem::path& dir,
                            const std::vector<ColumnSpec>& columns, int shard_count,
                            const std::string& metadata_json, const std::string& dataset_id = "");

/// A complete dataset opened for reading: the manifest parsed and checked, each shard file
/// open (one file descriptor per column per shard, held until the reader is destroyed).
///
/// Thread-safe: all const members may be called from several threads at once (reads use
/// pread on the descriptors, which keep no shared file position). Movable, not copyable; a
/// moved-from reader may only be destroyed or assigned to.
class DatasetReader {
 public:
  /// Opens the dataset in `dir`. Throws FileFormatError naming the file and the field:
  /// manifest.json missing ("holds no complete dataset"), larger than 64 MiB, not JSON,
  /// nested deeper than 64 levels, format other than "ropes-dataset", format_version other
  /// than 1, malformed columns (name, dtype, row_shape; duplicates) or shards (rows > 0,
  /// files naming exactly the columns at their canonical paths, bytes, 64-digit sha256),
  /// rows that differ from the shards' sum, metadata that is not an object; a shard file
  /// that cannot be opened, whose .npy header is not the column's dtype and shape
  /// [shard rows, row_shape...], or whose size differs from its header or the manifest.
  /// Cost: reads the manifest and each file's header; data is not read (see verify()).
  static DatasetReader open(const std::filesystem::path& dir);

  DatasetReader(DatasetReader&&) noexcept;
  DatasetReader& operator=(DatasetReader&&) noexcept;
  DatasetReader(const DatasetReader&) = delete;
  DatasetReader& operator=(const DatasetReader&) = delete;
  ~DatasetReader();

  const std::filesystem::path& dir() const;
  /// Rows of every column, over all shards.
  std::int64_t rows() const;
  int shard_count() const;
  /// The columns in manifest order.
  const std::vector<ColumnSpec>& columns() const;
  /// The column called `name`; throws std::out_of_range naming it and listing the columns.
  const ColumnSpec& column(const std::string& name) const;
  /// The manifest's metadata object as compact JSON text.
  const std::string& metadata_json() const;
  /// The same, parsed (include <nlohmann/json.hpp> to use it).
  const nlohmann::json& metadata() const;
  /// The metadata value at `json_pointer` (RFC 6901, e.g. "/regimes/1/joint"). A value the
  /// dataset lacks (written by an older writer, say) is a FileFormatError naming
  /// manifest.json, the pointer and `hint` (what to do about it); a pointer that is not
  /// RFC 6901 syntax is std::invalid_argument.
  const nlohmann::json& metadata_at(const std::string& json_pointer,
                                    const std::string& hint = "") const;

  /// Copies rows [first, first + count) of `column` into `out`, which must hold
  /// count * (bytes of one row) bytes, rows in order, C order within a row. The range may
  /// span shards. Throws std::out_of_range for an unknown column or a range outside
  /// [0, rows()) (naming the range and rows()); FileFormatError naming the file when a read
  /// fails or ends early (a file truncated after open()). count == 0 copies nothing.
  void read_rows(const std::string& column, std::int64_t first, std::int64_t count,
                 void* out) const;
  /// As above, into a new array of the column's dtype and shape [count, row_shape...].
  NpyArray read_rows(const std::string& column, std::int64_t first, std::int64_t count) const;

  /// Gathers the rows `rows` (any order, repeats allowed) of `column` into `out`, which must
  /// hold rows.size() rows, in the order given. Runs of consecutive rows are read with one
  /// pread per shard. Throws std::out_of_range for an unknown column or a row outside
  /// [0, rows()) (naming its position in `rows` and its value), FileFormatError as
  /// read_rows. Nothing is read before every row is checked.
  void read_rows_at(const std::string& column, const std::vector<std::int64_t>& rows,
                    void* out) const;
  /// As above, into a new array of shape [rows.size(), row_shape...].
  NpyArray read_rows_at(const std::string& column, const std::vector<std::int64_t>& rows) const;

  /// Rows of shard `shard`; std::out_of_range outside [0, shard_count()).
  std::int64_t shard_rows(int shard) const;

  /// Shard `shard`'s rows of `column`, memory-mapped read-only from the file open() checked:
  /// no copy is made, pages are read when touched. `data` holds shard_rows(shard) rows, C
  /// order; the mapping lives as long as any copy of `mapping`, also after the reader is
  /// destroyed. Throws std::out_of_range for an unknown column or shard, FileFormatError
  /// naming the file when it cannot be mapped.
  struct MappedRows {
    std::shared_ptr<const void> mapping;
    const std::uint8_t* data = nullptr;
    DType dtype = DType::kU8;
    std::vector<std::int64_t> shape;  // [shard rows, row_shape...]
  };
  MappedRows map_shard(const std::string& column, int shard) const;

  /// Recomputes the SHA-256 of every shard file (through the open descriptors, so it checks
  /// what read_rows() serves) and compares it with the manifest. Throws FileFormatError
  /// naming the file, the expected and the actual hash on the first mismatch. Cost: reads
  /// every byte of the dataset once.
  void verify() const;

 private:
  struct State;
  explicit DatasetReader(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

/// A permutation of [0, n) that depends only on (n, seed, epoch): the order in which an
/// epoch visits a dataset's rows. Drawn from PhiloxStream(seed, kShuffleStreamBase + epoch)
/// (the base keeps these streams apart from the per-sample streams 0, 1, 2, ... of a
/// generator that uses the same seed) by Fisher-Yates: for i = n - 1 down to 1, swap
/// element i with element j, j uniform on [0, i] by rejection: with bound = i + 1, draw
/// words w (32 bits while bound < 2^32, else 64 bits from two words, low word first) until
/// w >= (2^bits - bound) mod bound, then j = w mod bound. Throws std::invalid_argument for
/// n < 0. Cost: O(n) time and memory.
inline constexpr std::uint64_t kShuffleStreamBase = 0x5348554600000000ull;  // "SHUF" << 32
std::vector<std::int64_t> shuffled_indices(std::int64_t n, std::uint64_t seed, std::uint64_t epoch);

}  // namespace ropes::core
