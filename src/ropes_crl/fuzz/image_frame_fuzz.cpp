// image_frame_fuzz: what ropes-stream does with the bytes of ImageFrame samples from the
// network. The input is a sequence of samples, each a 2-byte little-endian length and that
// many bytes of serialized payload (encapsulation header, then CDR), as Fast DDS hands
// them to the type support. Each is deserialized by the type support ropes-stream's
// Subscriber registers (ropes_msgs/dds.hpp: a sample that does not deserialize is
// dropped) and given to ropes-stream's
// FrameGrouper for a run of 2 cameras at 8x8. Every complete instant's pixels are read
// whole; a refused frame is counted. Nothing may crash, leak or allocate what the input's
// size does not justify. Corpus: good and bad frame sequences (ropes_crl_fuzz_make_corpus).
#include <ropes_msgs/dds.hpp>

#include <cstddef>
#include <cstdint>
#include <cstdlib>
#include <vector>

#include <ropes_crl/frame_grouper.hpp>

extern "C" int LLVMFuzzerTestOneInput(const std::uint8_t* data, std::size_t size) {
  using namespace ropes::crl::stream;
  constexpr int kCameras = 2, kSize = 8;
  unsigned long long completed = 0, sum = 0;
  FrameGrouper grouper(
      kCameras, kSize,
      [&](unsigned long long, std::int64_t, const std::uint8_t* pixels, Clock::time_point) {
        for (int i = 0; i < kCameras * kSize * kSize; ++i)
          sum += pixels[i];
        ++completed;
      },
      false);
  ropes::msgs::detail::CheckedPubSub<ropes::msgs::ImageFramePubSubType> type;
  std::size_t pos = 0, frames = 0;
  while (pos + 2 <= size) {
    const std::size_t n = data[pos] | (static_cast<std::size_t>(data[pos + 1]) << 8);
    pos += 2;
    if (n > size - pos)
      break;
    eprosima::fastrtps::rtps::SerializedPayload_t payload(static_cast<std::uint32_t>(n));
    std::copy(data + pos, data + pos + n, payload.data);
    payload.length = static_cast<std::uint32_t>(n);
    pos += n;
    ropes::msgs::ImageFrame frame;
    if (!type.deserialize(&payload, &frame))
      continue;
    grouper.on_frame(frame);
    ++frames;
  }
  if (completed + grouper.rejected() > frames)
    std::abort();
  (void)sum;
  return 0;
}
