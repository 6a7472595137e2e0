// JSON read from files: bounded nesting, one exception naming the file, values described
// without dump().
#include "ropes_core/json_text.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>

#include "ropes_core/file_format_error.hpp"

namespace ropes::core {
namespace {

namespace fs = std::filesystem;

std::string nested(int depth) {
  return std::string(depth, '[') + std::string(depth, ']');
}

fs::path write(const std::string& name, const std::string& text) {
  const fs::path p = fs::temp_directory_path() / (name + "." + std::to_string(::getpid()));
  std::ofstream(p) << text;
  return p;
}

std::string error_of(const fs::path& p) {
  try {
    read_json_file(p);
  } catch (const FileFormatError& e) {
    return e.what();
  }
  return "(no FileFormatError)";
}

TEST(JsonText, NestingIsBoundedAtTheLimit) {
  nlohmann::json v;
  EXPECT_EQ(parse_json(nested(kMaxJsonDepth), &v), "");
  EXPECT_EQ(parse_json(nested(kMaxJsonDepth + 1), &v), "nests deeper than 64 levels");
  EXPECT_TRUE(parse_json_or_discarded(nested(kMaxJsonDepth + 1)).is_discarded());
  EXPECT_TRUE(parse_json_or_discarded("{\"a\": ").is_discarded());
  EXPECT_EQ(parse_json_or_discarded("{\"a\": [1, 2]}")["a"][1], 2);
}

TEST(JsonText, AFileThatIsNotJsonIsRefusedByName) {
  const fs::path good = write("ropes_json_good", "{\"k\": 1}");
  EXPECT_EQ(read_json_file(good)["k"], 1);
  const fs::path bad = write("ropes_json_bad", "{\"k\": ");
  EXPECT_EQ(error_of(bad).rfind(bad.string() + ": is not JSON: ", 0), 0u) << error_of(bad);
  const fs::path deep = write("ropes_json_deep", nested(100));
  EXPECT_EQ(error_of(deep), deep.string() + ": nests deeper than 64 levels");
  const fs::path big = write("ropes_json_big", "[" + std::string(100, ' ') + "]");
  try {
    read_json_file(big, 16);
    FAIL() << "read a file over its limit";
  } catch (const FileFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("holds 102 bytes; expected at most 16"), std::string::npos)
        << e.what();
  }
  EXPECT_NE(error_of(fs::temp_directory_path() / "ropes_json_missing").find("cannot open"),
            std::string::npos);
  for (const fs::path& p : {good, bad, deep, big})
    fs::remove(p);
}

TEST(JsonText, AFileThatMayBeAbsentIsDiscardedWhenMissingOrNotJson) {
  const fs::path good = write("ropes_json_present", "{\"k\": 2}");
  EXPECT_EQ(read_json_file_if_present(good)["k"], 2);
  const fs::path bad = write("ropes_json_present_bad", "{\"k\": ");
  EXPECT_TRUE(read_json_file_if_present(bad).is_discarded());
  EXPECT_TRUE(
      read_json_file_if_present(fs::temp_directory_path() / "ropes_json_absent").is_discarded());
  // a folder, and a name too long to look at: not a file, no throw
  EXPECT_TRUE(read_json_file_if_present(fs::temp_directory_path()).is_discarded());
  EXPECT_FALSE(core::is_regular_file(fs::temp_directory_path() / std::string(5000, 'x')));
  EXPECT_TRUE(core::is_regular_file(good));
  // there but over the limit: refused, not taken for absent
  EXPECT_THROW(read_json_file_if_present(good, 4), FileFormatError);
  for (const fs::path& p : {good, bad})
    fs::remove(p);
}

TEST(JsonText, DescribeShowsAValueWithoutItsContents) {
  EXPECT_EQ(describe(nlohmann::json("abc")), "\"abc\"");
  EXPECT_EQ(describe(nlohmann::json(std::string(50, 'x'))), "\"" + std::string(40, 'x') + "...\"");
  EXPECT_EQ(describe(nlohmann::json(-3)), "-3");
  EXPECT_EQ(describe(nlohmann::json::parse(nested(60))), "a JSON array");
  EXPECT_EQ(describe_sizes(nlohmann::json::parse("[2, 3, -1]")), "[2,3,?]");
}

}  // namespace
}  // namespace ropes::core
