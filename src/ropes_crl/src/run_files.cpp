#include "run_files.hpp"

#include <ropes_core/file_format_error.hpp>
#include <ropes_core/file_io.hpp>
#include <ropes_nn/module.hpp>

#include <unistd.h>

#include <cerrno>
#include <cstdio>
#include <cstring>
#include <fstream>
#include <sstream>

namespace ropes::crl::detail {

void write_json_file(const fs::path& path, const nlohmann::json& j) {
  const std::string text = j.dump(2) + "\n";
  core::write_text_file_atomically(path, text);
}

std::vector<std::string> MetricsLog::lines() const {
  std::vector<std::string> out;
  std::error_code ec;
  if (!fs::exists(path_, ec))
    return out;
  std::istringstream in(core::read_text_file(path_, core::kMaxLogFileBytes));
  std::string line;
  while (std::getline(in, line))
    if (!line.empty())
      out.push_back(line);
  return out;
}

void MetricsLog::rewrite(const std::vector<std::string>& lines) const {
  std::string text;
  for (const std::string& l : lines)
    text += l + "\n";
  core::write_text_file_atomically(path_, text);
}

void MetricsLog::append(const nlohmann::json& record) const {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::FILE* f = std::fopen(path_.c_str(), "a");
  if (f == nullptr)
    throw core::FileFormatError(path_.string() + ": cannot be opened for appending");
  const std::string line = record.dump() + "\n";
  const bool written = std::fwrite(line.data(), 1, line.size(), f) == line.size();
  const int write_errno = errno;
  const bool closed = std::fclose(f) == 0;
  if (!written || !closed) {
    // a torn last line is dropped when the stage resumes (truncate)
    throw core::FileFormatError(path_.string() + ": a record could not be written: " +
                                std::strerror(written ? errno : write_errno));
  }
  if (observer_)
    observer_(record);
}

void ProgressBoard::draw() {
  std::string line = "\r" + title_;
  for (const auto& [owner, part] : parts_)
    line += " | " + part;
  line += "\x1b[K";
  std::fputs(line.c_str(), stderr);
  std::fflush(stderr);
}

void ProgressBoard::show(const std::string& owner, const std::string& part) {
  const std::lock_guard<std::mutex> lock(mutex_);
  parts_[owner] = part;
  draw();
}

void ProgressBoard::retire(const std::string& owner, const std::string& line) {
  const std::lock_guard<std::mutex> lock(mutex_);
  parts_.erase(owner);
  std::fprintf(stderr, "\r\x1b[K%s", line.c_str());
  if (!parts_.empty())
    draw();
  else
    std::fflush(stderr);
}

void ProgressBoard::print(const std::string& line) {
  const std::lock_guard<std::mutex> lock(mutex_);
  std::fputs(line.c_str(), stderr);
  std::fflush(stderr);
}

Progress::Progress(std::string stage, std::int64_t total, std::int64_t first, bool bar,
                   std::int64_t log_every, ProgressBoard* board)
    : stage_(std::move(stage)),
      total_(total),
      first_(first),
      bar_(bar),
      log_every_(log_every),
      board_(board),
      start_(std::chrono::steady_clock::now()) {}

void Progress::update(std::int64_t step, double loss, const std::string& extra) {
  if (!bar_ && step % log_every_ != 0 && step != total_)
    return;
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  const double done = static_cast<double>(step - first_);
  const double eta = done > 0 ? elapsed / done * static_cast<double>(total_ - step) : 0.0;
  char line[256];
  if (bar_ && board_ != nullptr) {
    // a short part of the shared line: the stage (less the line's title), step and ETA
    const std::string& title = board_->title();
    const std::string name =
        stage_.rfind(title + " ", 0) == 0 ? stage_.substr(title.size() + 1) : stage_;
    std::snprintf(line, sizeof line, "%s %lld/%lld ETA %.0fs", name.c_str(),
                  static_cast<long long>(step), static_cast<long long>(total_), eta);
    board_->show(stage_, line);
    return;
  }
  if (bar_) {
    const int width = 24;
    const int filled = static_cast<int>(width * step / std::max<std::int64_t>(total_, 1));
    std::string b(static_cast<std::size_t>(filled), '#');
    b.resize(width, '.');
    std::snprintf(line, sizeof line, "\r%-14s [%s] %lld/%lld loss %.5f ETA %4.0fs %s\x1b[K",
                  stage_.c_str(), b.c_str(), static_cast<long long>(step),
                  static_cast<long long>(total_), loss, eta, extra.c_str());
  } else {
    std::snprintf(line, sizeof line, "ropes-train: %s step %lld/%lld loss %.5f ETA %.0fs %s\n",
                  stage_.c_str(), static_cast<long long>(step), static_cast<long long>(total_),
                  loss, eta, extra.c_str());
  }
  if (board_ != nullptr) {
    board_->print(line);
    return;
  }
  std::fputs(line, stderr);
  std::fflush(stderr);
}

void Progress::finish(const std::string& summary) {
  const double elapsed =
      std::chrono::duration<double>(std::chrono::steady_clock::now() - start_).count();
  char line[512];
  std::snprintf(line, sizeof line, "ropes-train: %s done in %.1f s: %s\n", stage_.c_str(), elapsed,
                summary.c_str());
  if (board_ != nullptr) {
    if (bar_)
      board_->retire(stage_, line);
    else
      board_->print(line);
    return;
  }
  std::fprintf(stderr, "%s%s", bar_ ? "\r\x1b[K" : "", line);
  std::fflush(stderr);
}

nn::Tensor gather_rows(const std::vector<float>& values, const std::vector<std::int64_t>& row,
                       const std::vector<std::int64_t>& rows) {
  std::int64_t per = 1;
  for (std::int64_t d : row)
    per *= d;
  nn::Buffer out(static_cast<std::size_t>(per) * rows.size());
  for (std::size_t i = 0; i < rows.size(); ++i)
    std::copy_n(values.data() + rows[i] * per, per, out.data() + i * per);
  std::vector<std::int64_t> shape{static_cast<std::int64_t>(rows.size())};
  shape.insert(shape.end(), row.begin(), row.end());
  return nn::Tensor(nn::Shape(shape), std::move(out));
}

std::vector<std::int64_t> StepSampler::rows(std::int64_t step) {
  std::vector<std::int64_t> out;
  out.reserve(static_cast<std::size_t>(batch_));
  for (std::int64_t k = step * batch_; k < (step + 1) * batch_; ++k) {
    const std::int64_t epoch = k / n_;
    if (epoch != cached_epoch_) {
      perm_ = core::shuffled_indices(n_, seed_, static_cast<std::uint64_t>(epoch));
      cached_epoch_ = epoch;
    }
    out.push_back(perm_[static_cast<std::size_t>(k % n_)]);
  }
  return out;
}

std::uint64_t derive_seed(std::uint64_t seed, const std::string& what) {
  return nn::fnv1a64(std::to_string(seed) + "/" + what);
}

}  // namespace ropes::crl::detail
