#include "ropes_crl/frame_grouper.hpp"

#include <algorithm>
#include <cstdio>
#include <utility>

namespace ropes::crl::stream {

FrameGrouper::FrameGrouper(int cameras, int size, Complete complete, bool log, std::string name)
    : cameras_(cameras),
      size_(size),
      image_(static_cast<std::size_t>(size) * static_cast<std::size_t>(size)),
      complete_(std::move(complete)),
      log_(log),
      name_(std::move(name)) {}

std::string FrameGrouper::problem(const msgs::ImageFrame& f) const {
  const std::size_t n = f.camera_names().size();
  if (f.encoding() != "mono8")
    return "encoding '" + f.encoding() + "', expected mono8";
  if (f.width() != size_ || f.height() != size_)
    return "size " + std::to_string(f.width()) + "x" + std::to_string(f.height()) +
           ", the run's images are " + std::to_string(size_) + "x" + std::to_string(size_);
  if (n == 0 || f.camera_ids().size() != n)
    return std::to_string(n) + " camera names and " + std::to_string(f.camera_ids().size()) +
           " camera ids, expected as many of each (at least one)";
  if (f.pixels().size() != n * image_)
    return std::to_string(f.pixels().size()) + " pixel bytes for " + std::to_string(n) +
           " camera(s) of " + std::to_string(size_) + "x" + std::to_string(size_);
  std::vector<bool> seen(static_cast<std::size_t>(cameras_), false);
  for (const std::uint16_t id : f.camera_ids()) {
    if (id >= cameras_)
      return "camera id " + std::to_string(id) + ", the run has " + std::to_string(cameras_) +
             " camera(s)";
    if (seen[id])
      return "camera id " + std::to_string(id) + " twice";
    seen[id] = true;
  }
  return "";
}

void FrameGrouper::on_frame(const msgs::ImageFrame& f) {
  const Clock::time_point received = Clock::now();
  const std::string why = problem(f);
  if (!why.empty())
    return reject(f.sequence_number(), why);
  const unsigned long long seq = f.sequence_number();
  if (seq + 16 < done_below_) {
    // far behind what was answered: a publisher that started again from 0
    if (log_)
      std::fprintf(stderr, "%s: frame sequence restarted at %llu (was at %llu)\n", name_.c_str(),
                   seq, done_below_ - 1);
    groups_.clear();
    done_below_ = 0;
  }
  if (seq < done_below_ && groups_.count(seq) == 0)
    return reject(seq, "sequence number already answered or given up");
  Group& g = groups_[seq];
  if (g.have.empty()) {
    g.have.assign(static_cast<std::size_t>(cameras_), false);
    g.pixels.resize(static_cast<std::size_t>(cameras_) * image_);
    g.stamp_ns = f.stamp_ns();
  }
  for (std::size_t c = 0; c < f.camera_ids().size(); ++c) {
    const std::uint16_t id = f.camera_ids()[c];
    if (g.have[id]) {
      groups_.erase(seq);
      return reject(seq, "camera id " + std::to_string(id) + " sent twice for this instant");
    }
    g.have[id] = true;
    ++g.count;
    std::copy(f.pixels().begin() + static_cast<long>(c * image_),
              f.pixels().begin() + static_cast<long>((c + 1) * image_),
              g.pixels.begin() + static_cast<long>(id * image_));
  }
  g.received = received;
  if (g.count == cameras_) {
    const Group done = std::move(g);
    groups_.erase(seq);
    complete_(seq, done.stamp_ns, done.pixels.data(), done.received);
    if (seq + 1 > done_below_)
      done_below_ = seq + 1;
  }
  // instants that will not complete: more than 16 behind the newest
  while (!groups_.empty() && groups_.begin()->first + 16 < seq) {
    const auto first = groups_.begin()->first;
    groups_.erase(groups_.begin());
    reject(first, "incomplete: not every camera came");
  }
}

void FrameGrouper::reject(unsigned long long seq, const std::string& why) {
  ++rejected_;
  ++reasons_[why.substr(0, why.find_first_of("0123456789'"))];
  if (log_ && (rejected_ <= 20 || rejected_ % 1000 == 0))
    std::fprintf(stderr, "%s: frame %llu rejected (%llu so far): %s\n", name_.c_str(), seq,
                 static_cast<unsigned long long>(rejected_), why.c_str());
}

}  // namespace ropes::crl::stream
