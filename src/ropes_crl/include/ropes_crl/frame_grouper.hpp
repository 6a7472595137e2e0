#pragma once
/// @file frame_grouper.hpp
/// FrameGrouper: ropes-stream's handling of incoming ImageFrames, apart from DDS and the
/// Estimator so that it can be tested and fuzzed (fuzz/image_frame_fuzz.cpp): checks each
/// frame against the run (encoding, size, camera names and ids, pixel count), groups the
/// cameras of one instant by sequence number and hands every complete instant to
/// `complete`. A frame that cannot be used is refused: one log line naming it and the
/// reason, and a count. An instant still incomplete 16 sequence numbers after the newest is
/// given up; a sequence number far below the answered ones is a publisher that started
/// again, and grouping starts over.
///
/// In `ropes_crl::stream`, the library built with Fast DDS (ROPES_WITH_DDS); it links
/// ropes_msgs.
#include <ropes_msgs/ImageFrame.h>

#include <chrono>
#include <cstdint>
#include <functional>
#include <map>
#include <string>
#include <vector>

namespace ropes::crl::stream {

using Clock = std::chrono::steady_clock;

class FrameGrouper {
 public:
  /// An instant with every camera: its sequence number, stamp, the pixels of all cameras
  /// (camera id order, each size x size) and when its last frame arrived.
  using Complete = std::function<void(unsigned long long seq, std::int64_t stamp_ns,
                                      const std::uint8_t* pixels, Clock::time_point received)>;

  /// `log` false: refusals are counted, not printed (the fuzz harness); printed, they go to
  /// stderr as "<name>: frame N rejected ...".
  FrameGrouper(int cameras, int size, Complete complete, bool log = true,
               std::string name = "ropes-stream");

  /// Why `f` cannot be used ("" when it can).
  std::string problem(const msgs::ImageFrame& f) const;
  /// Takes one frame: refused, kept until its instant is complete, or completing it.
  void on_frame(const msgs::ImageFrame& f);
  /// Counts a refusal of instant `seq` and logs it (the first 20, then every 1000th).
  void reject(unsigned long long seq, const std::string& why);

  unsigned long long rejected() const { return rejected_; }
  /// refusals by the reason's first words
  const std::map<std::string, unsigned long long>& reasons() const { return reasons_; }
  /// instants waiting for a camera
  std::size_t pending() const { return groups_.size(); }

 private:
  // one instant's cameras, as they arrive
  struct Group {
    std::int64_t stamp_ns = 0;
    std::vector<bool> have;
    int count = 0;
    std::vector<std::uint8_t> pixels;
    Clock::time_point received;
  };

  int cameras_ = 0, size_ = 0;
  std::size_t image_ = 0;
  Complete complete_;
  bool log_ = true;
  std::string name_;
  std::map<unsigned long long, Group> groups_;
  unsigned long long done_below_ = 0, rejected_ = 0;
  std::map<std::string, unsigned long long> reasons_;
};

}  // namespace ropes::crl::stream
