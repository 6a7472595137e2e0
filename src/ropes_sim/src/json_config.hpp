#pragma once
// Private to ropes_sim: reading a JSON config file, shared by the config loaders.

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>

#include "ropes_core/file_format_error.hpp"
#include "ropes_core/file_io.hpp"
#include "ropes_sim/intervention_sampler.hpp"  // ConfigError

namespace ropes::sim::detail {

// the JSON object in `path`; ConfigError naming the file when it cannot be opened, is not
// JSON or is not an object. `what` names the kind of file in the message.
inline nlohmann::json read_config_object(const std::filesystem::path& path, const char* what) {
  const std::string file = path.string();
  std::string text;
  try {
    text = core::read_text_file(path, core::kMaxJsonFileBytes);  // a huge file: refused by size
  } catch (const core::FileFormatError& e) {
    throw ConfigError(std::string(e.what()) + " (the " + what + ")");
  }
  nlohmann::json config;
  // nlohmann's message says where the text stops being JSON: keep it
  try {
    config = nlohmann::json::parse(text);
  } catch (const nlohmann::json::exception& e) {
    throw ConfigError(file + ": not JSON: " + e.what());
  }
  if (!config.is_object())
    throw ConfigError(file + ": the config is not a JSON object");
  return config;
}

}  // namespace ropes::sim::detail
