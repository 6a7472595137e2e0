// FrameGrouper: the cameras of one instant grouped by sequence number, whatever frames they
// come in; frames that cannot be used refused with the reason and counted; instants that
// will not complete given up; a publisher that starts again from 0 followed.
#include "ropes_crl/frame_grouper.hpp"

#include <gtest/gtest.h>

#include <cstdint>
#include <string>
#include <vector>

namespace ropes::crl::stream {
namespace {

constexpr int kSize = 4;

// a frame of instant `seq` with the cameras `ids`; pixel i of camera id c is c * 100 + i
msgs::ImageFrame frame(unsigned long long seq, const std::vector<std::uint16_t>& ids) {
  msgs::ImageFrame f;
  f.stamp_ns(1000 + static_cast<std::int64_t>(seq));
  f.sequence_number(seq);
  std::vector<std::string> names;
  std::vector<std::uint8_t> pixels;
  for (const std::uint16_t id : ids) {
    names.push_back("camera" + std::to_string(id));
    for (int i = 0; i < kSize * kSize; ++i)
      pixels.push_back(static_cast<std::uint8_t>(id * 100 + i));
  }
  f.camera_names(names);
  f.camera_ids(ids);
  f.width(kSize);
  f.height(kSize);
  f.encoding("mono8");
  f.pixels(pixels);
  return f;
}

struct Completed {
  unsigned long long seq;
  std::int64_t stamp_ns;
  std::vector<std::uint8_t> pixels;
};

class FrameGrouperTest : public ::testing::Test {
 protected:
  FrameGrouper grouper_{
      2, kSize,
      [this](unsigned long long seq, std::int64_t stamp, const std::uint8_t* pixels,
             Clock::time_point) {
        done_.push_back(
            {seq, stamp, std::vector<std::uint8_t>(pixels, pixels + 2 * kSize * kSize)});
      },
      /*log=*/false};
  std::vector<Completed> done_;
};

TEST_F(FrameGrouperTest, GroupsTheCamerasOfAnInstantInCameraIdOrder) {
  grouper_.on_frame(frame(0, {1, 0}));  // both cameras in one frame, id 1 first
  grouper_.on_frame(frame(1, {1}));     // one camera a frame
  EXPECT_EQ(grouper_.pending(), 1u);
  grouper_.on_frame(frame(1, {0}));
  ASSERT_EQ(done_.size(), 2u);
  for (const Completed& c : done_) {
    EXPECT_EQ(c.stamp_ns, 1000 + static_cast<std::int64_t>(c.seq));
    EXPECT_EQ(c.pixels[0], 0);  // camera 0 first
    EXPECT_EQ(c.pixels[kSize * kSize - 1], kSize * kSize - 1);
    EXPECT_EQ(c.pixels[kSize * kSize], 100);  // then camera 1
  }
  EXPECT_EQ(done_[0].seq, 0u);
  EXPECT_EQ(done_[1].seq, 1u);
  EXPECT_EQ(grouper_.pending(), 0u);
  EXPECT_EQ(grouper_.rejected(), 0u);
}

TEST_F(FrameGrouperTest, RefusesFramesItCannotUseNamingTheReason) {
  msgs::ImageFrame f = frame(0, {0});
  f.encoding("rgb8");
  EXPECT_EQ(grouper_.problem(f), "encoding 'rgb8', expected mono8");
  f = frame(0, {0});
  f.width(kSize + 1);
  EXPECT_EQ(grouper_.problem(f), "size 5x4, the run's images are 4x4");
  f = frame(0, {0});
  f.pixels().pop_back();
  EXPECT_EQ(grouper_.problem(f), "15 pixel bytes for 1 camera(s) of 4x4");
  EXPECT_EQ(grouper_.problem(frame(0, {2})), "camera id 2, the run has 2 camera(s)");
  EXPECT_EQ(grouper_.problem(frame(0, {0, 0})), "camera id 0 twice");
  f = frame(0, {0});
  f.camera_ids({});
  EXPECT_EQ(grouper_.problem(f),
            "1 camera names and 0 camera ids, expected as many of each (at "
            "least one)");
  grouper_.on_frame(f);
  // a camera sent twice for one instant drops the instant
  grouper_.on_frame(frame(3, {0}));
  grouper_.on_frame(frame(3, {0}));
  EXPECT_EQ(grouper_.pending(), 0u);
  EXPECT_EQ(grouper_.rejected(), 2u);
  EXPECT_TRUE(done_.empty());
  // an answered instant again
  grouper_.on_frame(frame(4, {0, 1}));
  grouper_.on_frame(frame(4, {0, 1}));
  EXPECT_EQ(done_.size(), 1u);
  EXPECT_EQ(grouper_.rejected(), 3u);
  EXPECT_EQ(grouper_.reasons().size(), 3u);
}

TEST_F(FrameGrouperTest, GivesUpIncompleteInstantsAndFollowsARestart) {
  grouper_.on_frame(frame(0, {0}));  // camera 1 never comes
  for (unsigned long long seq = 1; seq <= 16; ++seq)
    grouper_.on_frame(frame(seq, {0, 1}));
  EXPECT_EQ(grouper_.rejected(), 0u);  // 16 behind the newest: still waited for
  grouper_.on_frame(frame(17, {0, 1}));
  EXPECT_EQ(grouper_.rejected(), 1u);
  EXPECT_EQ(grouper_.reasons().count("incomplete: not every camera came"), 1u);
  EXPECT_EQ(grouper_.pending(), 0u);
  // the publisher starts again at 0: grouped, not refused as answered
  grouper_.on_frame(frame(0, {0, 1}));
  EXPECT_EQ(done_.back().seq, 0u);
  EXPECT_EQ(done_.size(), 18u);
  EXPECT_EQ(grouper_.rejected(), 1u);
}

}  // namespace
}  // namespace ropes::crl::stream
