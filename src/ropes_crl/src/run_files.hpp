#pragma once
// Private helpers of the trainer and the estimator: the run directory's file names, its
// metadata conventions, JSON files written atomically, the metrics log, the progress line.
#include <ropes_core/dataset.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_nn/tensor.hpp>

#include <nlohmann/json.hpp>

#include <chrono>
#include <cstdint>
#include <filesystem>
#include <functional>
#include <map>
#include <mutex>
#include <string>
#include <vector>

namespace ropes::crl::detail {

namespace fs = std::filesystem;

inline constexpr const char* kRunFormat = "ropes-run";
inline constexpr int kRunFormatVersion = 1;
inline constexpr const char* kNetworkKey = "ropes.network";
inline constexpr const char* kConfigKey = "ropes.config";

inline fs::path ae1_file(const fs::path& run) {
  return run / "ae1.safetensors";
}
inline fs::path codes_file(const fs::path& run) {
  return run / "codes.npy";
}
inline fs::path ldr_file(const fs::path& run, const std::string& joint) {
  return run / ("ldr." + joint + ".safetensors");
}
inline fs::path ae2_file(const fs::path& run, const std::string& model) {
  return run / ("ae2." + model + ".safetensors");
}
inline fs::path checkpoint_of(const fs::path& weights) {
  fs::path p = weights;
  p.replace_extension(".checkpoint.safetensors");
  return p;
}

/// Writes `j` (indented) to `path` through a temporary and a rename.
void write_json_file(const fs::path& path, const nlohmann::json& j);

/// metrics.jsonl: appends one line per record and flushes it; truncate() drops the records
/// a resumed stage will write again (and a torn last line of a killed run). Safe to call from
/// several threads (the AE2s that train at once): each call holds the log's lock.
class MetricsLog {
 public:
  /// `observer` (may be empty) sees every record appended, after it is written.
  explicit MetricsLog(fs::path path, std::function<void(const nlohmann::json&)> observer = nullptr)
      : path_(std::move(path)), observer_(std::move(observer)) {}
  /// Keeps the records for which keep(record) is true (and only well-formed lines).
  template <class Keep>
  void truncate(Keep keep) const;
  void append(const nlohmann::json& record) const;

 private:
  void rewrite(const std::vector<std::string>& lines) const;
  std::vector<std::string> lines() const;
  fs::path path_;
  std::function<void(const nlohmann::json&)> observer_;
  mutable std::mutex mutex_;
};

template <class Keep>
void MetricsLog::truncate(Keep keep) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::vector<std::string> kept;
  for (const std::string& line : lines()) {
    const nlohmann::json j = core::parse_json_or_discarded(line);
    if (!j.is_discarded() && j.is_object() && keep(j))
      kept.push_back(line);
  }
  rewrite(kept);
}

/// The one terminal line that several stages running at once share (the AE2s trained side
/// by side): each Progress on the board owns a part of the line, and every update redraws
/// the whole line under the board's lock.
class ProgressBoard {
 public:
  explicit ProgressBoard(std::string title) : title_(std::move(title)) {}
  /// Sets (or replaces) `owner`'s part and redraws the line.
  void show(const std::string& owner, const std::string& part);
  /// Removes `owner`'s part, prints `line` (a finished stage's summary) on a line of its own
  /// and redraws what is left.
  void retire(const std::string& owner, const std::string& line);
  /// Serialises a plain log line with the board's other output.
  void print(const std::string& line);
  /// What the line starts with ("ae2"); a part leaves it out of its stage's name.
  const std::string& title() const { return title_; }

 private:
  void draw();
  std::string title_;
  std::map<std::string, std::string> parts_;
  std::mutex mutex_;
};

/// Progress of one stage: a bar rewritten in place on a terminal, plain lines otherwise.
/// With a board, the bar is a short part of the board's shared line instead.
class Progress {
 public:
  Progress(std::string stage, std::int64_t total, std::int64_t first, bool bar,
           std::int64_t log_every, ProgressBoard* board = nullptr);
  /// After step `step` (1-based) with the current loss.
  void update(std::int64_t step, double loss, const std::string& extra = "");
  void finish(const std::string& summary);

 private:
  std::string stage_;
  std::int64_t total_, first_;
  bool bar_;
  std::int64_t log_every_;
  ProgressBoard* board_;
  std::chrono::steady_clock::time_point start_;
};

/// Rows [n, ...row] of `values` (row-major, `per` floats a row) as a tensor of shape
/// [rows.size(), row...].
nn::Tensor gather_rows(const std::vector<float>& values, const std::vector<std::int64_t>& row,
                       const std::vector<std::int64_t>& rows);

/// The rows of step s of an endless stream of seeded epochs over n items, b a step:
/// positions [s*b, (s+1)*b) of perm(0) ++ perm(1) ++ ..., perm(e) = shuffled_indices(n,
/// seed, e). A pure function of (n, b, seed, s): a resumed run draws the same batches.
class StepSampler {
 public:
  StepSampler(std::int64_t n, std::int64_t batch, std::uint64_t seed)
      : n_(n), batch_(batch), seed_(seed) {}
  std::vector<std::int64_t> rows(std::int64_t step);

 private:
  std::int64_t n_, batch_;
  std::uint64_t seed_;
  std::int64_t cached_epoch_ = -1;
  std::vector<std::int64_t> perm_;
};

/// A seed for one named part of a run (the init of a network, a data order).
std::uint64_t derive_seed(std::uint64_t seed, const std::string& what);

}  // namespace ropes::crl::detail
