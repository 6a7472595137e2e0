#pragma once
// Private to ropes_sim: reading a JSON config file and its fields, shared by the config loaders.

#include <nlohmann/json.hpp>

#include <filesystem>
#include <fstream>
#include <string>

#include "ropes_core/file_format_error.hpp"
#include "ropes_core/file_io.hpp"
#include "ropes_core/json_text.hpp"
#include "ropes_sim/intervention_sampler.hpp"  // ConfigError

namespace ropes::sim::detail {

// a ConfigError "<file>: <what>"
[[noreturn]] inline void fail(const std::string& file, const std::string& what) {
  throw ConfigError(file + ": " + what);
}

// v as a number; ConfigError naming the file, the field and the value otherwise
inline double number(const nlohmann::json& v, const std::string& file, const std::string& field) {
  if (!v.is_number())
    fail(file, field + " is " + core::describe(v) + "; expected a number");
  return v.get<double>();
}

// the JSON object in `path`; ConfigError naming the file when it cannot be opened, is not
// JSON or is not an object. `what` names the kind of file in the message.
inline nlohmann::json read_config_object(const std::filesystem::path& path, const char* what) {
  // a huge file is refused by its size; nlohmann's message says where the text stops being JSON
  nlohmann::json config;
  try {
    config = core::read_json_file(path);
  } catch (const core::FileFormatError& e) {
    throw ConfigError(std::string(e.what()) + " (the " + what + ")");
  }
  if (!config.is_object())
    throw ConfigError(path.string() + ": the config is not a JSON object");
  return config;
}

}  // namespace ropes::sim::detail
