#pragma once
// Command-line helpers shared by ropes-eval and ropes-run (private to ropes_eval's tools);
// usage errors, number flags and run_main: ropes_core/cli.hpp.
#include <ropes_core/cli.hpp>
#include <ropes_core/file_io.hpp>
#include <ropes_crl/calibration.hpp>
#include <ropes_eval/suites.hpp>

#include <algorithm>
#include <cstdint>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

namespace ropes::eval::tools {

namespace fs = std::filesystem;

using core::parse_number;
using core::UsageError;

inline void write_text(const fs::path& path, const std::string& text) {
  ropes::core::write_file_atomically(path, reinterpret_cast<const std::uint8_t*>(text.data()),
                                     text.size());
}

/// crl::evaluation_output, an --out inside the run a usage error.
inline fs::path evaluation_output(const std::string& run_dir, const std::string& out,
                                  const fs::path& name) {
  try {
    return crl::evaluation_output(run_dir, out, name);
  } catch (const std::invalid_argument& e) {
    throw UsageError((out.empty() ? std::string("--run: ") : std::string("--out ")) + e.what());
  }
}

inline std::vector<std::string> split_list(const std::string& flag, const std::string& text) {
  std::vector<std::string> out;
  std::size_t start = 0;
  while (start <= text.size()) {
    const std::size_t comma = text.find(',', start);
    const std::string item =
        text.substr(start, comma == std::string::npos ? std::string::npos : comma - start);
    if (item.empty())
      throw UsageError(flag + " is '" + text + "'; expected a comma-separated list");
    out.push_back(item);
    if (comma == std::string::npos)
      break;
    start = comma + 1;
  }
  return out;
}

/// --repeats R, --calibration-samples C, --test-samples N and --probe-steps N into `options`,
/// each in its range of eval::check_protocol, the flag named in the usage error.
inline core::CommandLine& add_protocol_options(core::CommandLine& command_line,
                                               RunEvaluationOptions& options) {
  const auto count = [](const char* flag, std::int64_t* field, ProtocolRange range) {
    return [flag, field, range](const std::string& v) {
      const auto value = parse_number<std::int64_t>(flag, v);
      if (!range.holds(value))
        throw UsageError(std::string(flag) + " is " + v + "; expected " + range.text());
      *field = value;
    };
  };
  return command_line.option("--repeats", count("--repeats", &options.repeats, kRepeatsRange))
      .option("--calibration-samples",
              count("--calibration-samples", &options.calibration_samples, kSamplesRange))
      .option("--test-samples", count("--test-samples", &options.test_samples, kSamplesRange))
      .option("--probe-steps", count("--probe-steps", &options.probe_steps, kProbeStepsRange));
}

/// --suite's value: suites, comma-separated (ropes::eval::check_suites)
inline std::vector<std::string> parse_suites(const std::string& flag, const std::string& value) {
  std::vector<std::string> out = split_list(flag, value);
  try {
    check_suites(out);
  } catch (const std::invalid_argument& e) {
    throw UsageError(flag + ": " + e.what());
  }
  return out;
}

/// --supervised's value: percentages in (0, 100], comma-separated, as fractions ascending and
/// each once; "none": none.
inline std::vector<double> parse_supervised(const std::string& flag, const std::string& value) {
  std::vector<double> out;
  if (value == "none")
    return out;
  for (const std::string& v : split_list(flag, value)) {
    const auto pct = parse_number<double>(flag, v);
    if (!(pct > 0 && pct <= 100))
      throw UsageError(flag + " has " + v + "; expected percentages in (0, 100]");
    out.push_back(pct / 100.0);
  }
  std::sort(out.begin(), out.end());
  out.erase(std::unique(out.begin(), out.end()), out.end());
  return out;
}

}  // namespace ropes::eval::tools
