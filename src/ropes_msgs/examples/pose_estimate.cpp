// Example from the ropes_msgs README: fill a PoseEstimate and serialize it with the type
// support a DDS DomainParticipant registers.
#include <ropes_msgs/PoseEstimatePubSubTypes.h>

#include <cstdio>

int main() {
  ropes::msgs::PoseEstimate estimate;
  estimate.frame_index(7);
  estimate.latents({0.31f, -1.2f, 0.05f});
  estimate.joint_angles({0.1f, -0.4f, 1.2f});
  estimate.model_id("small-1c-seed0");

  ropes::msgs::PoseEstimatePubSubType type;  // register_type(participant) in a real node
  eprosima::fastrtps::rtps::SerializedPayload_t payload(
      type.getSerializedSizeProvider(&estimate)());
  if (!type.serialize(&estimate, &payload))
    return 1;
  std::printf("%s: %u bytes on the wire\n", type.getName(), payload.length);
  return 0;
}
