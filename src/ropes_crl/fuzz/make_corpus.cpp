// ropes_crl_fuzz_make_corpus DIR: writes the seed corpus of the image_frame harness into
// DIR/image_frame/ (fuzz/corpus/ holds what it wrote): sequences of serialized ImageFrame
// samples, each a 2-byte little-endian length and the payload. Run by hand when the IDL
// changes.
#include <ropes_msgs/ImageFramePubSubTypes.h>

#include <cstdint>
#include <cstdio>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace fs = std::filesystem;

namespace {

ropes::msgs::ImageFrame frame(unsigned long long seq, std::vector<std::uint16_t> ids,
                              const std::string& encoding = "mono8", int size = 8) {
  ropes::msgs::ImageFrame f;
  f.stamp_ns(1000 + static_cast<long long>(seq));
  f.sequence_number(seq);
  std::vector<std::string> names;
  for (const std::uint16_t id : ids)
    names.push_back(id == 0 ? "front" : "side");
  f.camera_names(names);
  f.camera_ids(ids);
  f.width(static_cast<std::uint16_t>(size));
  f.height(static_cast<std::uint16_t>(size));
  f.encoding(encoding);
  std::vector<std::uint8_t> pixels(ids.size() * static_cast<std::size_t>(size * size));
  for (std::size_t i = 0; i < pixels.size(); ++i)
    pixels[i] = static_cast<std::uint8_t>(i * 7 + seq);
  f.pixels(pixels);
  return f;
}

void write(const fs::path& file, const std::vector<ropes::msgs::ImageFrame>& frames) {
  ropes::msgs::ImageFramePubSubType type;
  std::string bytes;
  for (ropes::msgs::ImageFrame f : frames) {
    eprosima::fastrtps::rtps::SerializedPayload_t payload(type.getSerializedSizeProvider(&f)());
    if (!type.serialize(&f, &payload))
      throw std::runtime_error("cannot serialize");
    bytes += static_cast<char>(payload.length & 0xff);
    bytes += static_cast<char>(payload.length >> 8);
    bytes.append(reinterpret_cast<const char*>(payload.data), payload.length);
  }
  fs::create_directories(file.parent_path());
  std::ofstream(file, std::ios::binary) << bytes;
  std::printf("%s (%zu bytes)\n", file.c_str(), bytes.size());
}

}  // namespace

int main(int argc, char** argv) {
  if (argc != 2) {
    std::fprintf(stderr, "usage: %s DIR\n", argv[0]);
    return 2;
  }
  const fs::path out = fs::path(argv[1]) / "image_frame";
  write(out / "both_cameras.bin", {frame(0, {0, 1}), frame(1, {1, 0})});
  write(out / "split_cameras.bin",
        {frame(0, {0}), frame(0, {1}), frame(1, {1}), frame(2, {0}), frame(1, {0})});
  write(out / "refused_then_good.bin", {frame(0, {0, 1}, "rgb8"), frame(1, {0, 1}, "mono8", 16),
                                        frame(2, {0, 0}), frame(3, {0, 1})});
  write(out / "restart.bin", {frame(40, {0, 1}), frame(41, {0, 1}), frame(0, {0, 1})});
  return 0;
}
