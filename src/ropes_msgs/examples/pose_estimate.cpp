// Example from the ropes_msgs README: fill a PoseEstimate and serialize it with the type
// support a DDS DomainParticipant registers.
#include <ropes_msgs/PoseEstimatePubSubTypes.h>

#include <cstdio>

int main() {
  ropes::msgs::PoseEstimate estimate;
  estimate.frame_sequence_number(7);
  estimate.run_id("small-1c-seed0");
  estimate.latents({0.31f, -1.2f, 0.05f});
  estimate.joint_names({"panda_joint2", "panda_joint4", "panda_joint6"});
  estimate.joint_angles({0.1f, -0.4f, 1.2f});
  estimate.valid({true, true, true});

  ropes::msgs::PoseEstimatePubSubType type;  // register_type(participant) in a real node
  eprosima::fastrtps::rtps::SerializedPayload_t payload(
      type.getSerializedSizeProvider(&estimate)());
  if (!type.serialize(&estimate, &payload))
    return 1;
  std::printf("%s: %u bytes on the wire\n", type.getName(), payload.length);
  return 0;
}
