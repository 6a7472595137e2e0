#pragma once
// Reading the JSON files of a run or a dataset (private to ropes_eval).
#include <ropes_nn/npy.hpp>

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <sstream>

namespace ropes::eval::detail {

// the file's JSON; nn::FileFormatError naming it when it cannot be opened or parsed
inline nlohmann::json read_json_file(const std::filesystem::path& path) {
  std::ifstream in(path);
  if (!in)
    throw nn::FileFormatError(path.string() + ": cannot be opened");
  std::stringstream text;
  text << in.rdbuf();
  const nlohmann::json j = nlohmann::json::parse(text.str(), nullptr, false);
  if (j.is_discarded())
    throw nn::FileFormatError(path.string() + ": not valid JSON");
  return j;
}

}  // namespace ropes::eval::detail
