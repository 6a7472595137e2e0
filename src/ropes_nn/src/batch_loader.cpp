#include "ropes_nn/batch_loader.hpp"

#include <algorithm>
#include <condition_variable>
#include <cstring>
#include <exception>
#include <mutex>
#include <optional>
#include <set>
#include <stdexcept>
#include <thread>
#include <utility>

namespace ropes::nn {

namespace {

std::string value_list(const std::vector<std::int64_t>& values) {
  std::string out = "{";
  for (std::size_t i = 0; i < values.size() && i < 16; ++i)
    out += (i ? ", " : "") + std::to_string(values[i]);
  return out + (values.size() > 16 ? ", ...}" : "}");
}

// one integer per row of a u8, i32 or i64 column
std::vector<std::int64_t> integer_values(const core::NpyArray& a) {
  const std::size_t n = static_cast<std::size_t>(a.shape.empty() ? 0 : a.shape[0]);
  std::vector<std::int64_t> out(n);
  for (std::size_t i = 0; i < n; ++i) {
    switch (a.dtype) {
      case core::DType::kU8:
        out[i] = a.data[i];
        break;
      case core::DType::kI32: {
        std::int32_t v;
        std::memcpy(&v, a.data.data() + 4 * i, 4);
        out[i] = v;
        break;
      }
      default: {
        std::int64_t v;
        std::memcpy(&v, a.data.data() + 8 * i, 8);
        out[i] = v;
        break;
      }
    }
  }
  return out;
}

// a column's bytes as floats: u8 / 255, others converted
void to_floats(const core::NpyArray& a, float* out) {
  const std::int64_t n = a.element_count();
  const std::uint8_t* p = a.data.data();
  for (std::int64_t i = 0; i < n; ++i) {
    switch (a.dtype) {
      case core::DType::kU8:
        out[i] = static_cast<float>(p[i]) / 255.0f;
        break;
      case core::DType::kI32: {
        std::int32_t v;
        std::memcpy(&v, p + 4 * i, 4);
        out[i] = static_cast<float>(v);
        break;
      }
      case core::DType::kI64: {
        std::int64_t v;
        std::memcpy(&v, p + 8 * i, 8);
        out[i] = static_cast<float>(v);
        break;
      }
      case core::DType::kF32:
        std::memcpy(out + i, p + 4 * i, 4);
        break;
      case core::DType::kF64: {
        double v;
        std::memcpy(&v, p + 8 * i, 8);
        out[i] = static_cast<float>(v);
        break;
      }
    }
  }
}

}  // namespace

std::vector<RowRange> split_rows(std::int64_t n, std::int64_t max_rows) {
  if (n < 0 || max_rows < 1) {
    throw std::invalid_argument("split_rows: n = " + std::to_string(n) + ", max_rows = " +
                                std::to_string(max_rows) + "; expected n >= 0, max_rows >= 1");
  }
  const std::int64_t parts = (n + max_rows - 1) / max_rows;
  std::vector<RowRange> out;
  std::int64_t begin = 0;
  for (std::int64_t p = 0; p < parts; ++p) {
    const std::int64_t size = n / parts + (p < n % parts ? 1 : 0);
    out.push_back({begin, begin + size});
    begin += size;
  }
  return out;
}

const Tensor& Batch::tensor(const std::string& name) const {
  const auto it = tensors.find(name);
  if (it == tensors.end()) {
    throw std::out_of_range("Batch::tensor: no column '" + name +
                            "' read as a tensor (BatchLoaderOptions::columns)");
  }
  return it->second;
}

const core::NpyArray& Batch::array(const std::string& name) const {
  const auto it = arrays.find(name);
  if (it == arrays.end()) {
    throw std::out_of_range("Batch::array: no column '" + name +
                            "' read as stored (BatchLoaderOptions::raw_columns)");
  }
  return it->second;
}

struct BatchLoader::State {
  const core::DatasetReader& reader;
  BatchLoaderOptions options;
  std::vector<std::int64_t> rows;
  DataCursor cursor;

  // an epoch's order of positions into `rows`, kept per thread that builds batches
  struct Order {
    std::int64_t epoch = -1;
    std::vector<std::int64_t> positions;
  };
  Order main_order;

  // the read-ahead thread and what it shares with the caller (under `mutex`)
  std::mutex mutex;
  std::condition_variable changed;
  std::optional<DataCursor> pending;  // asked for, not started
  bool working = false;
  DataCursor working_on;
  std::optional<DataCursor> done_cursor;  // the result below is for this cursor
  std::optional<Batch> done;
  std::exception_ptr done_error;
  bool stop = false;
  std::thread worker;

  State(const core::DatasetReader& r, BatchLoaderOptions o) : reader(r), options(std::move(o)) {}

  std::int64_t batch_rows(const DataCursor& c) const {
    return std::min(options.batch_size, static_cast<std::int64_t>(rows.size()) - c.position);
  }

  DataCursor after(const DataCursor& c) const {
    DataCursor next{c.epoch, c.position + batch_rows(c)};
    const auto total = static_cast<std::int64_t>(rows.size());
    if (next.position >= total || (options.drop_last && next.position + options.batch_size > total))
      next = {c.epoch + 1, 0};
    return next;
  }

  // the batch at `c`: a pure function of the dataset, the options and `c`
  Batch build(const DataCursor& c, Order* order) const {
    if (options.shuffle && order->epoch != c.epoch) {
      order->positions = core::shuffled_indices(static_cast<std::int64_t>(rows.size()),
                                                options.seed, static_cast<std::uint64_t>(c.epoch));
      order->epoch = c.epoch;
    }
    Batch b;
    b.cursor = c;
    b.index = c.position / options.batch_size;
    const std::int64_t n = batch_rows(c);
    for (std::int64_t k = c.position; k < c.position + n; ++k) {
      const auto at = static_cast<std::size_t>(options.shuffle ? order->positions[k] : k);
      b.rows.push_back(rows[at]);
    }
    for (const std::string& name : options.columns) {
      const core::NpyArray raw = reader.read_rows_at(name, b.rows);
      Buffer values(static_cast<std::size_t>(raw.element_count()));
      to_floats(raw, values.data());
      b.tensors.emplace(name, Tensor(Shape(raw.shape), std::move(values)));
    }
    for (const std::string& name : options.raw_columns)
      b.arrays.emplace(name, reader.read_rows_at(name, b.rows));
    return b;
  }

  void run_worker() {
    Order order;
    std::unique_lock<std::mutex> lock(mutex);
    for (;;) {
      changed.wait(lock, [&] { return stop || pending.has_value(); });
      if (stop)
        return;
      const DataCursor c = *pending;
      pending.reset();
      working = true;
      working_on = c;
      lock.unlock();
      std::optional<Batch> batch;
      std::exception_ptr error;
      try {
        batch = build(c, &order);
      } catch (...) {
        error = std::current_exception();
      }
      lock.lock();
      working = false;
      if (!pending) {  // a newer request makes this one stale
        done_cursor = c;
        done = std::move(batch);
        done_error = error;
      }
      changed.notify_all();
    }
  }

  void request(const DataCursor& c) {
    {
      const std::lock_guard<std::mutex> lock(mutex);
      pending = c;
      done_cursor.reset();
      done.reset();
      done_error = nullptr;
    }
    changed.notify_all();
  }
};

BatchLoader::BatchLoader(const core::DatasetReader& reader, BatchLoaderOptions options)
    : state_(std::make_unique<State>(reader, std::move(options))) {
  State& s = *state_;
  const BatchLoaderOptions& o = s.options;
  constexpr const char* kWhere = "BatchLoader: ";
  if (o.batch_size < 1) {
    throw std::invalid_argument(std::string(kWhere) + "batch_size is " +
                                std::to_string(o.batch_size) + "; expected >= 1");
  }
  if (o.columns.empty() && o.raw_columns.empty())
    throw std::invalid_argument(std::string(kWhere) + "no columns to read; name at least one");
  std::set<std::string> names;
  for (const auto* list : {&o.columns, &o.raw_columns}) {
    for (const std::string& name : *list) {
      const core::ColumnSpec& spec = reader.column(name);  // std::out_of_range naming it
      if (!names.insert(name).second) {
        throw std::invalid_argument(std::string(kWhere) + "column '" + name +
                                    "' is named twice; expected each column once");
      }
      if (list == &o.columns && spec.row_shape.size() > 3) {
        throw std::invalid_argument(std::string(kWhere) + "column '" + name + "' has rows of " +
                                    std::to_string(spec.row_shape.size()) +
                                    " dimensions; a tensor batch holds at most 3 (read it as a "
                                    "raw column)");
      }
    }
  }

  // the rows to draw from: the list (checked) or all, then the filter
  std::vector<std::int64_t> candidates = o.rows;
  for (std::size_t i = 0; i < candidates.size(); ++i) {
    if (candidates[i] < 0 || candidates[i] >= reader.rows()) {
      throw std::out_of_range(std::string(kWhere) + "rows[" + std::to_string(i) + "] is " +
                              std::to_string(candidates[i]) + "; the dataset " +
                              reader.dir().string() + " has rows 0.." +
                              std::to_string(reader.rows() - 1));
    }
  }
  if (o.rows.empty()) {
    candidates.resize(static_cast<std::size_t>(reader.rows()));
    for (std::int64_t r = 0; r < reader.rows(); ++r)
      candidates[static_cast<std::size_t>(r)] = r;
  }
  if (o.filter_column.empty() != o.filter_values.empty()) {
    throw std::invalid_argument(
        std::string(kWhere) +
        (o.filter_column.empty()
             ? "filter_values given without a filter_column"
             : "filter_column '" + o.filter_column + "' given without filter_values"));
  }
  if (!o.filter_column.empty()) {
    const core::ColumnSpec& spec = reader.column(o.filter_column);
    if (!spec.row_shape.empty() || spec.dtype == core::DType::kF32 ||
        spec.dtype == core::DType::kF64) {
      throw std::invalid_argument(std::string(kWhere) + "filter_column '" + o.filter_column +
                                  "' is " + core::dtype_name(spec.dtype) + " with rows of shape [" +
                                  std::to_string(spec.row_shape.size()) +
                                  " dims]; expected an integer column (u8, i32, i64) of one "
                                  "value per row");
    }
    const std::vector<std::int64_t> values =
        integer_values(o.rows.empty() ? reader.read_rows(o.filter_column, 0, reader.rows())
                                      : reader.read_rows_at(o.filter_column, candidates));
    const std::set<std::int64_t> wanted(o.filter_values.begin(), o.filter_values.end());
    for (std::size_t i = 0; i < candidates.size(); ++i) {
      if (wanted.count(values[i]))
        s.rows.push_back(candidates[i]);
    }
    if (s.rows.empty()) {
      const auto [lo, hi] = std::minmax_element(values.begin(), values.end());
      throw std::invalid_argument(std::string(kWhere) + "no row of " + reader.dir().string() +
                                  " has " + o.filter_column + " in " + value_list(o.filter_values) +
                                  (values.empty() ? std::string()
                                                  : "; its values lie in " + std::to_string(*lo) +
                                                        ".." + std::to_string(*hi)));
    }
  } else {
    s.rows = std::move(candidates);
  }
  if (s.rows.empty()) {
    throw std::invalid_argument(std::string(kWhere) + "no rows to draw from in " +
                                reader.dir().string());
  }
  if (o.drop_last && static_cast<std::int64_t>(s.rows.size()) < o.batch_size) {
    throw std::invalid_argument(std::string(kWhere) + "drop_last with " +
                                std::to_string(s.rows.size()) + " rows and batch_size " +
                                std::to_string(o.batch_size) + " leaves no batch in an epoch");
  }

  if (o.prefetch) {
    s.worker = std::thread([&s] { s.run_worker(); });
    s.request(s.cursor);
  }
}

BatchLoader::~BatchLoader() {
  if (state_->worker.joinable()) {
    {
      const std::lock_guard<std::mutex> lock(state_->mutex);
      state_->stop = true;
    }
    state_->changed.notify_all();
    state_->worker.join();
  }
}

const std::vector<std::int64_t>& BatchLoader::rows() const {
  return state_->rows;
}

std::int64_t BatchLoader::batches_per_epoch() const {
  const auto r = static_cast<std::int64_t>(state_->rows.size());
  const std::int64_t b = state_->options.batch_size;
  return state_->options.drop_last ? r / b : (r + b - 1) / b;
}

DataCursor BatchLoader::cursor() const {
  return state_->cursor;
}

void BatchLoader::seek(const DataCursor& cursor) {
  State& s = *state_;
  const auto total = static_cast<std::int64_t>(s.rows.size());
  const bool fits = s.options.drop_last ? cursor.position + s.options.batch_size <= total
                                        : cursor.position < total;
  if (cursor.epoch < 0 || cursor.position < 0 || !fits) {
    throw std::invalid_argument(
        "BatchLoader::seek: epoch " + std::to_string(cursor.epoch) + ", position " +
        std::to_string(cursor.position) + "; expected epoch >= 0 and a position in [0, " +
        std::to_string(s.options.drop_last ? total - s.options.batch_size : total - 1) + "] (" +
        std::to_string(total) + " rows)");
  }
  s.cursor = cursor;
  if (s.worker.joinable())
    s.request(cursor);
}

Batch BatchLoader::next() {
  State& s = *state_;
  const DataCursor c = s.cursor;
  std::optional<Batch> batch;
  if (s.worker.joinable()) {
    std::unique_lock<std::mutex> lock(s.mutex);
    const bool coming = (s.pending && *s.pending == c) || (s.working && s.working_on == c) ||
                        (s.done_cursor && *s.done_cursor == c);
    if (coming) {
      s.changed.wait(lock, [&] { return !s.pending && !s.working; });
      if (s.done_cursor && *s.done_cursor == c) {
        if (s.done_error)
          std::rethrow_exception(std::exchange(s.done_error, nullptr));
        batch = std::move(s.done);
      }
    }
  }
  if (!batch)
    batch = s.build(c, &s.main_order);
  s.cursor = s.after(c);
  if (s.worker.joinable())
    s.request(s.cursor);
  return std::move(*batch);
}

}  // namespace ropes::nn
