#pragma once
/// @file batch_loader.hpp
/// BatchLoader: seeded batches of a core::DatasetReader's rows as float tensors, read ahead on a
/// background thread.
///
/// Which rows: all of the dataset's, or an explicit list (a train or held-out split), then
/// optionally only those whose integer column `filter_column` holds one of `filter_values`
/// (say, the rows of one regime). Call these the loader's rows, R of them.
/// In what order: epoch e visits the loader's rows in the order
/// core::shuffled_indices(R, seed, e) (or in list order with shuffle off), `batch_size` at a time;
/// the last batch of an epoch is smaller unless drop_last. The batches depend only on the
/// dataset, the options and the cursor — not on the thread count, the prefetching or what
/// was read before — so a run that resumes at a cursor sees the same batches.
/// What each batch holds: for every column in `columns` a float tensor [n, row_shape...]
/// (rank <= 4): u8 values divided by 255 (images in [0, 1]), other dtypes converted; for
/// every column in `raw_columns` the rows as stored (an core::NpyArray of the column's dtype).
///
/// Not thread-safe: one thread calls next() and seek(). The loader keeps a reference to the
/// reader: the reader must outlive the loader and stay where it is (not moved from).

#include <cstdint>
#include <map>
#include <memory>
#include <string>
#include <vector>

#include "ropes_core/dataset.hpp"
#include "ropes_nn/tensor.hpp"

namespace ropes::nn {

/// Where a loader stands: the next batch starts at `position` of epoch `epoch`'s order.
struct DataCursor {
  std::int64_t epoch = 0;
  std::int64_t position = 0;
  bool operator==(const DataCursor& o) const { return epoch == o.epoch && position == o.position; }
  bool operator!=(const DataCursor& o) const { return !(*this == o); }
};

struct BatchLoaderOptions {
  std::vector<std::string> columns;      ///< read as float tensors (u8 scaled into [0, 1])
  std::vector<std::string> raw_columns;  ///< read as stored
  std::int64_t batch_size = 64;          ///< >= 1
  std::uint64_t seed = 0;
  bool shuffle = true;     ///< false: the rows in order, every epoch
  bool drop_last = false;  ///< true: an epoch has only full batches
  /// The rows to draw from (dataset row numbers, each in [0, rows())); empty: all rows.
  std::vector<std::int64_t> rows;
  /// Keep only rows whose value in this column (a u8, i32 or i64 column with one value per
  /// row) is one of filter_values. Empty: no filter.
  std::string filter_column;
  std::vector<std::int64_t> filter_values;
  /// Read the next batch on a background thread while the caller works on this one.
  bool prefetch = true;
};

/// Rows [begin, end) of a batch: one micro-batch.
struct RowRange {
  std::int64_t begin = 0, end = 0;
  std::int64_t size() const { return end - begin; }
};

/// [0, n) split into ceil(n / max_rows) contiguous parts of near-equal size (sizes differ by
/// at most one, larger ones first). max_rows >= 1 and n >= 0 (std::invalid_argument).
std::vector<RowRange> split_rows(std::int64_t n, std::int64_t max_rows);

struct Batch {
  DataCursor cursor;               ///< where this batch starts
  std::int64_t index = 0;          ///< batch number within its epoch
  std::vector<std::int64_t> rows;  ///< the dataset rows it holds, in order
  std::map<std::string, Tensor> tensors;
  std::map<std::string, core::NpyArray> arrays;

  std::int64_t size() const { return static_cast<std::int64_t>(rows.size()); }
  /// The tensor of column `name`; std::out_of_range naming it when the loader did not read it
  /// as a tensor.
  const Tensor& tensor(const std::string& name) const;
  const core::NpyArray& array(const std::string& name) const;
  /// split_rows(size(), max_rows).
  std::vector<RowRange> micro_batches(std::int64_t max_rows) const {
    return split_rows(size(), max_rows);
  }
};

class BatchLoader {
 public:
  /// Checks the options against the dataset and reads the filter column. Throws
  /// std::invalid_argument for batch_size < 1, no columns, a column named twice, a filter
  /// without values or values without a filter; std::out_of_range naming the column or row
  /// for a column the dataset lacks or a row outside it; std::invalid_argument for a filter
  /// column that is not an integer column of one value per row, a float column whose rows do
  /// not fit a tensor (rank > 4), or no rows left to draw from (naming the filter), or an
  /// epoch with no batch (drop_last with fewer rows than batch_size).
  BatchLoader(const core::DatasetReader& reader, BatchLoaderOptions options);
  ~BatchLoader();
  BatchLoader(const BatchLoader&) = delete;
  BatchLoader& operator=(const BatchLoader&) = delete;

  /// The rows the loader draws from (after the list and the filter), in dataset order for a
  /// filter over all rows, else in list order.
  const std::vector<std::int64_t>& rows() const;
  std::int64_t batches_per_epoch() const;
  /// The cursor of the batch next() returns next.
  DataCursor cursor() const;
  /// Moves to `cursor` (epoch >= 0, 0 <= position < rows(), and with drop_last a position
  /// that leaves a full batch; std::invalid_argument otherwise). A batch read ahead for
  /// another cursor is dropped.
  void seek(const DataCursor& cursor);
  /// The batch at the cursor; the cursor moves past it (to the next epoch after the last
  /// batch). Errors reading the dataset (core::FileFormatError) surface here.
  Batch next();

 private:
  struct State;
  std::unique_ptr<State> state_;
};

}  // namespace ropes::nn
