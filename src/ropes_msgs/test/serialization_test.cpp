// Round trips of the generated types through Fast DDS's own serializer, and the exact CDR
// bytes of one small sample of each type.
#include <ropes_msgs/ImageFramePubSubTypes.h>
#include <ropes_msgs/JointStatePubSubTypes.h>
#include <ropes_msgs/PoseEstimatePubSubTypes.h>
#include <ropes_msgs/RunStatusPubSubTypes.h>

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace {

using eprosima::fastrtps::rtps::SerializedPayload_t;
using Bytes = std::vector<uint8_t>;

template <typename PubSubType, typename Message>
SerializedPayload_t serialize(const Message& message) {
  PubSubType type;
  SerializedPayload_t payload(type.getSerializedSizeProvider(const_cast<Message*>(&message))());
  EXPECT_TRUE(type.serialize(const_cast<Message*>(&message), &payload));
  return payload;
}

template <typename PubSubType, typename Message>
Message round_trip(const Message& message) {
  SerializedPayload_t payload = serialize<PubSubType>(message);
  PubSubType type;
  Message back;
  EXPECT_TRUE(type.deserialize(&payload, &back));
  return back;
}

// the payload is `expected` followed by at most 3 bytes of zero padding
void expect_layout(const SerializedPayload_t& payload, const Bytes& expected) {
  ASSERT_GE(payload.length, expected.size());
  EXPECT_EQ(Bytes(payload.data, payload.data + expected.size()), expected);
  for (uint32_t i = static_cast<uint32_t>(expected.size()); i < payload.length; ++i) {
    EXPECT_EQ(payload.data[i], 0) << "byte " << i;
  }
  EXPECT_LT(payload.length, expected.size() + 4);
}

ropes::msgs::ImageFrame two_camera_frame() {
  ropes::msgs::ImageFrame frame;
  frame.stamp_ns(-42);
  frame.sequence_number(123456789012ull);
  frame.camera_names({"yaw45", "yaw135"});
  frame.camera_ids({0, 1});
  frame.width(4);
  frame.height(3);
  frame.encoding("mono8");
  Bytes pixels(2 * 3 * 4);
  for (std::size_t i = 0; i < pixels.size(); ++i)
    pixels[i] = static_cast<uint8_t>(i * 11);
  frame.pixels(pixels);
  return frame;
}

TEST(RopesMsgs, ImageFrameRoundTripsThroughCdr) {
  const ropes::msgs::ImageFrame frame = two_camera_frame();
  const auto back = round_trip<ropes::msgs::ImageFramePubSubType>(frame);
  EXPECT_EQ(back, frame);
  EXPECT_EQ(back.pixels().size(), 24u);
  EXPECT_EQ(back.camera_names()[1], "yaw135");
}

TEST(RopesMsgs, JointStateRoundTripsThroughCdr) {
  ropes::msgs::JointState state;
  state.stamp_ns(1700000000123456789ll);
  state.sequence_number(9);
  state.names({"panda_joint2", "panda_joint4", "panda_joint6"});
  state.positions({0.25, -2.0, 1.5});
  EXPECT_EQ(round_trip<ropes::msgs::JointStatePubSubType>(state), state);
}

TEST(RopesMsgs, PoseEstimateRoundTripsThroughCdr) {
  ropes::msgs::PoseEstimate estimate;
  estimate.stamp_ns(1700000000123456789ll);
  estimate.sequence_number(7);
  estimate.frame_sequence_number(70);
  estimate.frame_stamp_ns(1700000000000000000ll);
  estimate.run_id("small-1c-seed0");
  estimate.latents({0.1f, 0.2f, 0.3f});
  estimate.joint_names({"panda_joint2", "panda_joint4", "panda_joint6"});
  estimate.joint_angles({-0.1f, 1.2f, 2.3f});
  estimate.valid({true, false, true});
  estimate.latency_ns(3500000);
  estimate.rejected_frames(2);
  EXPECT_EQ(round_trip<ropes::msgs::PoseEstimatePubSubType>(estimate), estimate);
}

TEST(RopesMsgs, RunStatusRoundTripsThroughCdr) {
  ropes::msgs::RunStatus status;
  status.stamp_ns(5);
  status.run_id("run");
  status.stage("ae2 panda_joint4");
  status.step(120);
  status.total_steps(4000);
  status.loss_names({"loss", "sparsity"});
  status.loss_values({0.031, 12.5});
  status.eta_s(61.5);
  EXPECT_EQ(round_trip<ropes::msgs::RunStatusPubSubType>(status), status);
}

// Witness for the layouts below: the bytes are worked out by hand from the OMG CDR rules
// (XCDR1, the encoding of @final structs: little-endian encapsulation 0x0001, primitives
// aligned to their own size, 8-byte ones included, counted from the end of the 4-byte
// encapsulation header; sequences and strings prefixed by a 32-bit length, strings counting
// their terminating NUL). Any DDS vendor reading XCDR1 agrees. Each sample puts an 8-byte
// value where XCDR2 (which aligns them to 4) would differ.
TEST(RopesMsgsGolden, ImageFrameHasTheHandComputedCdrLayout) {
  ropes::msgs::ImageFrame frame;
  frame.stamp_ns(-2);
  frame.sequence_number(0x0102030405060708ull);
  frame.camera_names({"a"});
  frame.camera_ids({3});
  frame.width(4);
  frame.height(1);
  frame.encoding("mono8");
  frame.pixels({1, 2, 3, 4});
  expect_layout(serialize<ropes::msgs::ImageFramePubSubType>(frame),
                {
                    0x00, 0x01, 0x00, 0x00,                          // encapsulation
                    0xfe, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,  // 0: stamp_ns = -2
                    0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01,  // 8: sequence_number
                    0x01, 0x00, 0x00, 0x00,                          // 16: camera_names: 1
                    0x02, 0x00, 0x00, 0x00, 'a',  0x00,              // 20: "a"
                    0x00, 0x00,                                      // 26: pad to 4
                    0x01, 0x00, 0x00, 0x00, 0x03, 0x00,              // 28: camera_ids {3}
                    0x04, 0x00,                                      // 34: width
                    0x01, 0x00,                                      // 36: height
                    0x00, 0x00,                                      // 38: pad to 4
                    0x06, 0x00, 0x00, 0x00, 'm',  'o',  'n',  'o',   // 40: "mono8"
                    '8',  0x00,                                      //
                    0x00, 0x00,                                      // 50: pad to 4
                    0x04, 0x00, 0x00, 0x00, 0x01, 0x02, 0x03, 0x04,  // 52: pixels
                });
}

TEST(RopesMsgsGolden, JointStateHasTheHandComputedCdrLayout) {
  ropes::msgs::JointState state;
  state.stamp_ns(5);
  state.sequence_number(1);
  state.names({"joint1"});
  state.positions({0.5});
  expect_layout(serialize<ropes::msgs::JointStatePubSubType>(state),
                {
                    0x00, 0x01, 0x00, 0x00,                          // encapsulation
                    0x05, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 0: stamp_ns
                    0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 8: sequence_number
                    0x01, 0x00, 0x00, 0x00,                          // 16: names: 1
                    0x07, 0x00, 0x00, 0x00, 'j',  'o',  'i',  'n',   // 20: "joint1"
                    't',  '1',  0x00,                                //
                    0x00,                                            // 31: pad to 4
                    0x01, 0x00, 0x00, 0x00,                          // 32: positions: 1
                    0x00, 0x00, 0x00, 0x00,                          // 36: pad to 8
                    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xe0, 0x3f,  // 40: 0.5
                });
}

TEST(RopesMsgsGolden, PoseEstimateHasTheHandComputedCdrLayout) {
  ropes::msgs::PoseEstimate estimate;
  estimate.stamp_ns(-2);
  estimate.sequence_number(3);
  estimate.frame_sequence_number(0x0102030405060708ull);
  estimate.frame_stamp_ns(1);
  estimate.run_id("r");
  estimate.latents({1.0f});
  estimate.joint_names({"j"});
  estimate.joint_angles({-0.5f});
  estimate.valid({true});
  estimate.latency_ns(1000);
  estimate.rejected_frames(2);
  expect_layout(serialize<ropes::msgs::PoseEstimatePubSubType>(estimate),
                {
                    0x00, 0x01, 0x00, 0x00,                          // encapsulation
                    0xfe, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,  // 0: stamp_ns = -2
                    0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 8: sequence_number
                    0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01,  // 16: frame_sequence_n.
                    0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 24: frame_stamp_ns
                    0x02, 0x00, 0x00, 0x00, 'r',  0x00,              // 32: run_id "r"
                    0x00, 0x00,                                      // 38: pad to 4
                    0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x80, 0x3f,  // 40: latents {1.0f}
                    0x01, 0x00, 0x00, 0x00,                          // 48: joint_names: 1
                    0x02, 0x00, 0x00, 0x00, 'j',  0x00,              // 52: "j"
                    0x00, 0x00,                                      // 58: pad to 4
                    0x01, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xbf,  // 60: angles {-0.5f}
                    0x01, 0x00, 0x00, 0x00, 0x01,                    // 68: valid {true}
                    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,        // 73: pad to 8
                    0xe8, 0x03, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 80: latency_ns 1000
                    0x02, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 88: rejected_frames
                });
}

TEST(RopesMsgsGolden, RunStatusHasTheHandComputedCdrLayout) {
  ropes::msgs::RunStatus status;
  status.stamp_ns(7);
  status.run_id("r");
  status.stage("ae1");
  status.step(10);
  status.total_steps(100);
  status.loss_names({"loss"});
  status.loss_values({0.25});
  status.eta_s(-1.0);
  expect_layout(serialize<ropes::msgs::RunStatusPubSubType>(status),
                {
                    0x00, 0x01, 0x00, 0x00,                          // encapsulation
                    0x07, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 0: stamp_ns
                    0x02, 0x00, 0x00, 0x00, 'r',  0x00,              // 8: run_id "r"
                    0x00, 0x00,                                      // 14: pad to 4
                    0x04, 0x00, 0x00, 0x00, 'a',  'e',  '1',  0x00,  // 16: stage "ae1"
                    0x0a, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 24: step
                    0x64, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0x00,  // 32: total_steps
                    0x01, 0x00, 0x00, 0x00,                          // 40: loss_names: 1
                    0x05, 0x00, 0x00, 0x00, 'l',  'o',  's',  's',   // 44: "loss"
                    0x00,                                            //
                    0x00, 0x00, 0x00,                                // 53: pad to 4
                    0x01, 0x00, 0x00, 0x00,                          // 56: loss_values: 1
                    0x00, 0x00, 0x00, 0x00,                          // 60: pad to 8
                    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xd0, 0x3f,  // 64: 0.25
                    0x00, 0x00, 0x00, 0x00, 0x00, 0x00, 0xf0, 0xbf,  // 72: eta_s -1.0
                });
}

}  // namespace
