// Round trips of the generated types through Fast DDS's own serializer, and the exact CDR
// bytes of a small PoseEstimate.
#include <ropes_msgs/FramePubSubTypes.h>
#include <ropes_msgs/PoseEstimatePubSubTypes.h>

#include <gtest/gtest.h>

#include <cstdint>
#include <vector>

namespace {

using eprosima::fastrtps::rtps::SerializedPayload_t;

template <typename PubSubType, typename Message>
SerializedPayload_t serialize(const Message& message) {
  PubSubType type;
  SerializedPayload_t payload(type.getSerializedSizeProvider(const_cast<Message*>(&message))());
  EXPECT_TRUE(type.serialize(const_cast<Message*>(&message), &payload));
  return payload;
}

template <typename PubSubType, typename Message>
Message deserialize(SerializedPayload_t& payload) {
  PubSubType type;
  Message message;
  EXPECT_TRUE(type.deserialize(&payload, &message));
  return message;
}

TEST(RopesMsgs, FrameRoundTripsThroughCdr) {
  ropes::msgs::Frame frame;
  frame.index(123456789012ull);
  frame.stamp_ns(-42);
  frame.cameras(2);
  frame.height(3);
  frame.width(4);
  std::vector<uint8_t> pixels(2 * 3 * 4);
  for (std::size_t i = 0; i < pixels.size(); ++i)
    pixels[i] = static_cast<uint8_t>(i * 11);
  frame.pixels(pixels);
  frame.joint_angles({0.0f, -0.5f, 0.25f, -2.0f, 0.0f, 1.5f, 0.79f});

  SerializedPayload_t payload = serialize<ropes::msgs::FramePubSubType>(frame);
  const ropes::msgs::Frame back =
      deserialize<ropes::msgs::FramePubSubType, ropes::msgs::Frame>(payload);
  EXPECT_EQ(back, frame);
  EXPECT_EQ(back.pixels(), pixels);
  EXPECT_EQ(back.joint_angles().size(), 7u);
}

TEST(RopesMsgs, PoseEstimateRoundTripsThroughCdr) {
  ropes::msgs::PoseEstimate estimate;
  estimate.frame_index(7);
  estimate.stamp_ns(1700000000123456789ll);
  estimate.latents({0.1f, 0.2f, 0.3f});
  estimate.joint_angles({-0.1f, 1.2f, 2.3f});
  estimate.model_id("small-1c-seed0");
  SerializedPayload_t payload = serialize<ropes::msgs::PoseEstimatePubSubType>(estimate);
  EXPECT_EQ((deserialize<ropes::msgs::PoseEstimatePubSubType, ropes::msgs::PoseEstimate>(payload)),
            estimate);
}

// Witness: the bytes below are worked out by hand from the OMG CDR rules (little-endian
// encapsulation 0x0001, primitives aligned to their size relative to the data after the
// 4-byte encapsulation header, sequences and strings prefixed by a 32-bit length, strings
// counting their terminating NUL). Any DDS vendor reading XCDR1 @final structs agrees.
TEST(RopesMsgsGolden, PoseEstimateHasTheHandComputedCdrLayout) {
  ropes::msgs::PoseEstimate estimate;
  estimate.frame_index(0x0102030405060708ull);
  estimate.stamp_ns(-2);
  estimate.latents({1.0f, -0.5f});
  estimate.model_id("ab");
  SerializedPayload_t payload = serialize<ropes::msgs::PoseEstimatePubSubType>(estimate);

  const std::vector<uint8_t> expected = {
      0x00, 0x01, 0x00, 0x00,                          // encapsulation: CDR little-endian
      0x08, 0x07, 0x06, 0x05, 0x04, 0x03, 0x02, 0x01,  // frame_index
      0xfe, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff, 0xff,  // stamp_ns = -2
      0x02, 0x00, 0x00, 0x00,                          // latents: length 2
      0x00, 0x00, 0x80, 0x3f, 0x00, 0x00, 0x00, 0xbf,  //   1.0f, -0.5f
      0x00, 0x00, 0x00, 0x00,                          // joint_angles: length 0
      0x03, 0x00, 0x00, 0x00, 'a',  'b',  0x00,        // model_id: length 3 with the NUL
  };
  ASSERT_GE(payload.length, expected.size());
  EXPECT_EQ(std::vector<uint8_t>(payload.data, payload.data + expected.size()), expected);
  // anything after the data is alignment padding
  for (uint32_t i = static_cast<uint32_t>(expected.size()); i < payload.length; ++i) {
    EXPECT_EQ(payload.data[i], 0) << "byte " << i;
  }
  EXPECT_LT(payload.length, expected.size() + 4);
}

}  // namespace
