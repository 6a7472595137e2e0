// fuzz_input.hpp: how the multi-file harnesses split one input into files.
#include <ropes_core/fuzz_input.hpp>

#include <gtest/gtest.h>

#include <cstdint>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace ropes::core::fuzz {
namespace {

std::vector<Section> split(const std::string& text) {
  return split_sections(reinterpret_cast<const std::uint8_t*>(text.data()), text.size());
}

TEST(FuzzInput, SectionsSplitAtMarkerLinesAndJoinBackToTheSameBytes) {
  const std::vector<Section> parts = {
      {"", "{\"a\": 1}\n"}, {"marker", "no newline at the end"}, {"x", ""}, {"y", "\n\n"}};
  const std::string joined = join_sections(parts);
  EXPECT_EQ(joined,
            "{\"a\": 1}\n\n==> marker <==\nno newline at the end\n==> x <==\n\n==> y <==\n\n\n");
  const std::vector<Section> back = split(joined);
  ASSERT_EQ(back.size(), parts.size());
  for (std::size_t i = 0; i < parts.size(); ++i) {
    EXPECT_EQ(back[i].name, parts[i].name) << i;
    EXPECT_EQ(back[i].bytes, parts[i].bytes) << i;
  }
  EXPECT_EQ(join_sections(back), joined);
}

TEST(FuzzInput, TextWithoutMarkersIsTheMainSectionAndNearMissesAreContent) {
  EXPECT_EQ(split("").size(), 1u);
  EXPECT_EQ(split("").front().bytes, "");
  const std::string near = "==> two words <==\n==>x <==\n ==> y <==\n==>  <==\nend";
  const std::vector<Section> one = split(near);
  ASSERT_EQ(one.size(), 1u);
  EXPECT_EQ(one.front().bytes, near);
  // binary bytes, NUL included, stay as they are
  const std::string binary("\0\x01\xff\n==> b <==\n\0", 15);
  const std::vector<Section> two = split(binary);
  ASSERT_EQ(two.size(), 2u);
  EXPECT_EQ(two[0].bytes, std::string("\0\x01\xff", 3));
  EXPECT_EQ(two[1].name, "b");
  EXPECT_EQ(two[1].bytes, std::string("\0", 1));
}

TEST(FuzzInput, ScratchDirWritesClearsAndIsRemoved) {
  std::filesystem::path root;
  {
    const ScratchDir scratch;
    root = scratch.path();
    const auto file = scratch.write("shards/00000.json", "{}");
    std::ifstream in(file);
    std::string text;
    in >> text;
    EXPECT_EQ(text, "{}");
    scratch.clear();
    EXPECT_TRUE(std::filesystem::is_directory(root));
    EXPECT_TRUE(std::filesystem::is_empty(root));
  }
  EXPECT_FALSE(std::filesystem::exists(root));
}

}  // namespace
}  // namespace ropes::core::fuzz
