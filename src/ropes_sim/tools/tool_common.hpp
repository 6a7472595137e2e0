#pragma once
// What ropes-generate and ropes-sim-stream share: usage errors, number flags and configs
// given by name.
#include <charconv>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace ropes::sim::tools {

namespace fs = std::filesystem;

struct UsageError : std::runtime_error {
  using std::runtime_error::runtime_error;
};

template <typename T>
T parse_number(const std::string& flag, const std::string& text, T lo, T hi) {
  T value{};
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || value < lo || value > hi)
    throw UsageError(flag + " is '" + text + "'; expected an integer in [" + std::to_string(lo) +
                     ", " + std::to_string(hi) + "]");
  return value;
}

// a finite number in [lo, hi]
inline double parse_real(const std::string& flag, const std::string& text, double lo, double hi) {
  double value = 0;
  const auto [end, ec] = std::from_chars(text.data(), text.data() + text.size(), value);
  if (ec != std::errc() || end != text.data() + text.size() || !(value >= lo && value <= hi))
    throw UsageError(flag + " is '" + text + "'; expected a number in [" + std::to_string(lo) +
                     ", " + std::to_string(hi) + "]");
  return value;
}

// a config given by name is looked for among the installed ones, next to this executable
inline fs::path find_config(const std::string& value) {
  if (fs::is_regular_file(value))
    return value;
  // next to the executable (an install tree moved elsewhere), then where it was installed
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  std::vector<fs::path> places;
  if (!ec)
    places.push_back(exe.parent_path().parent_path() / "share" / "ropes_sim" / "datasets");
  places.push_back(fs::path(ROPES_SIM_INSTALL_DATASETS_DIR));
  for (const fs::path& dir : places)
    if (fs::is_regular_file(dir / (value + ".json")))
      return dir / (value + ".json");
  throw UsageError("--config '" + value +
                   "' is neither a file nor an installed config name (1c, 2c, 2c_causal, ...)");
}

}  // namespace ropes::sim::tools
