#pragma once
// Reading a log that may be absent, and writing numbers (private to ropes_eval; a JSON file
// that may be absent: core::read_json_file_if_present).
#include <ropes_core/file_format_error.hpp>
#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>

#include <nlohmann/json.hpp>

#include <cmath>
#include <filesystem>
#include <sstream>
#include <string>
#include <vector>

namespace ropes::eval::detail {

// numbers as results files hold them: a JSON array, NaN and infinities as null
inline nlohmann::json numbers_or_null(const std::vector<double>& v) {
  nlohmann::json a = nlohmann::json::array();
  for (double x : v)
    a.push_back(std::isfinite(x) ? nlohmann::json(x) : nlohmann::json(nullptr));
  return a;
}

// the lines of a log that may be absent (none then); one over core::kMaxLogFileBytes is
// refused (core::FileFormatError)
inline std::vector<std::string> read_log_lines(const std::filesystem::path& path) {
  std::vector<std::string> lines;
  if (!core::is_regular_file(path))
    return lines;
  std::istringstream in(core::read_text_file(path, core::kMaxLogFileBytes));
  std::string line;
  while (std::getline(in, line))
    lines.push_back(line);
  return lines;
}

}  // namespace ropes::eval::detail
