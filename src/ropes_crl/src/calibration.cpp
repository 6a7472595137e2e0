#include "ropes_crl/calibration.hpp"

#include <ropes_core/file_format_error.hpp>
#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_core/sha256.hpp>

#include <algorithm>
#include <stdexcept>
#include <system_error>

#include "json_fields.hpp"
#include "ropes_crl/run_directory.hpp"

namespace ropes::crl {

namespace fs = std::filesystem;

namespace {
constexpr const char* kFormat = "ropes-calibration";
}  // namespace

RunIdentity RunIdentity::of(const RunDirectory& run) {
  RunIdentity id;
  id.config = run.config().name;
  const std::string config = run.config().to_json().dump();
  id.config_sha256 = core::sha256_hex(config.data(), config.size());
  id.dataset = run.dataset_id();
  id.seed = run.seed();
  return id;
}

bool RunIdentity::operator==(const RunIdentity& other) const {
  return config == other.config && config_sha256 == other.config_sha256 &&
         dataset == other.dataset && seed == other.seed;
}

std::string RunIdentity::describe() const {
  return "config " + config + " (sha256 " + config_sha256.substr(0, 12) + "...), seed " +
         std::to_string(seed) + ", dataset " + dataset.substr(0, 12) + "...";
}

AffineCalibration Calibration::joint(std::size_t k) const {
  if (k >= joints.size() || k >= scale.size() || k >= offset.size())
    throw std::out_of_range("Calibration::joint: joint " + std::to_string(k) + " of " +
                            std::to_string(joints.size()));
  return {scale[k], offset[k]};
}

nlohmann::json Calibration::to_json() const {
  nlohmann::json j = {
      {"format", kFormat}, {"joints", joints}, {"scale", scale}, {"offset", offset}};
  if (run)
    j["run"] = {{"config", run->config},
                {"config_sha256", run->config_sha256},
                {"seed", run->seed},
                {"dataset", run->dataset}};
  return j;
}

Calibration Calibration::from_json(const nlohmann::json& j) {
  Calibration c;
  if (j.is_object() && j.contains("format") && j["format"] != kFormat)
    throw std::invalid_argument("calibration.format: expected \"" + std::string(kFormat) +
                                "\", got " + core::describe(j["format"]));
  c.joints = detail::get_strings(j, "calibration", "joints");
  for (const char* key : {"scale", "offset"}) {
    const nlohmann::json& v = detail::field(j, "calibration", key);
    std::vector<double>& out = std::string(key) == "scale" ? c.scale : c.offset;
    if (!v.is_array() || v.size() != c.joints.size())
      throw std::invalid_argument(std::string("calibration.") + key + ": expected " +
                                  std::to_string(c.joints.size()) + " numbers, got " +
                                  core::describe(v));
    for (const nlohmann::json& e : v) {
      if (!e.is_number())
        throw std::invalid_argument(std::string("calibration.") + key + ": expected numbers, got " +
                                    core::describe(e));
      out.push_back(e.get<double>());
    }
  }
  if (j.contains("run")) {
    const nlohmann::json& r = j["run"];
    RunIdentity id;
    id.config = detail::get_string(r, "calibration.run", "config");
    id.config_sha256 = detail::get_string(r, "calibration.run", "config_sha256");
    id.dataset = detail::get_string(r, "calibration.run", "dataset");
    const nlohmann::json& seed = detail::field(r, "calibration.run", "seed");
    if (!seed.is_number_unsigned())
      throw std::invalid_argument("calibration.run.seed: expected a non-negative integer, got " +
                                  core::describe(seed));
    id.seed = seed.get<std::uint64_t>();
    c.run = id;
  }
  return c;
}

Calibration Calibration::read(const fs::path& file) {
  const nlohmann::json j = core::read_json_file(file);
  try {
    return from_json(j);
  } catch (const std::invalid_argument& e) {
    throw core::FileFormatError(file.string() + ": " + e.what());
  }
}

void Calibration::write(const fs::path& file) const {
  const std::string text = to_json().dump(2) + "\n";
  core::write_text_file_atomically(file, text);
}

void Calibration::check_fits(const RunDirectory& r) const {
  if (joints != r.joints()) {
    std::string have, want;
    for (const std::string& j : joints)
      have += (have.empty() ? "" : ",") + j;
    for (const std::string& j : r.joints())
      want += (want.empty() ? "" : ",") + j;
    throw std::invalid_argument("the calibration is for the joints " + have + ", the run " +
                                r.dir().string() + " estimates " + want);
  }
  if (run) {
    const RunIdentity id = RunIdentity::of(r);
    if (*run != id)
      throw std::invalid_argument("the calibration was fitted for another run (" + run->describe() +
                                  ") than " + r.dir().string() + " (" + id.describe() + ")");
  }
}

fs::path default_evaluation_dir(const fs::path& run_dir) {
  const auto strip = [](fs::path p) {  // "runs/a/" -> "runs/a"
    while (!p.has_filename() && p.has_relative_path())
      p = p.parent_path();
    return p;
  };
  fs::path dir = strip(run_dir.lexically_normal());
  if (dir.empty() || dir.filename() == "." || dir.filename() == "..")
    dir = strip(fs::absolute(run_dir).lexically_normal());
  if (!dir.has_relative_path())
    throw std::invalid_argument("a run directory cannot be " + run_dir.string() +
                                " (its evaluation goes beside it)");
  return dir.parent_path() / (dir.filename().string() + "-eval");
}

fs::path evaluation_output(const fs::path& run_dir, const fs::path& out, const fs::path& name) {
  if (out.empty())
    return default_evaluation_dir(run_dir) / name;
  const fs::path run = fs::weakly_canonical(fs::absolute(run_dir));
  const fs::path target = fs::weakly_canonical(fs::absolute(out));
  if (std::mismatch(run.begin(), run.end(), target.begin(), target.end()).first == run.end())
    throw std::invalid_argument(out.string() + " is inside the run directory " + run_dir.string() +
                                "; an evaluation is written apart from the run (default: " +
                                (default_evaluation_dir(run_dir) / name).string() + ")");
  return out;
}

std::vector<fs::path> calibration_candidates(const RunDirectory& run) {
  const fs::path eval = default_evaluation_dir(run.dir());
  std::vector<fs::path> out = {eval / "calibration.json", eval / "report" / "calibration.json"};
  // ropes-run's layout: OUT/run beside OUT/report and OUT/ropes-run.json
  const fs::path parent = eval.parent_path().empty() ? fs::path(".") : eval.parent_path();
  if (core::is_regular_file(parent / "ropes-run.json"))
    out.push_back(parent / "report" / "calibration.json");
  return out;
}

std::optional<fs::path> latest_calibration(const RunDirectory& run,
                                           std::vector<std::string>* skipped) {
  std::optional<fs::path> best;
  fs::file_time_type best_time{};
  for (const fs::path& file : calibration_candidates(run)) {
    if (!core::is_regular_file(file))
      continue;
    std::error_code ec;
    const fs::file_time_type written = fs::last_write_time(file, ec);
    if (ec)
      continue;
    try {
      Calibration::read(file).check_fits(run);
    } catch (const std::exception& e) {
      if (skipped != nullptr)
        skipped->push_back(file.string() + ": " + e.what());
      continue;
    }
    if (!best || written > best_time) {
      best = file;
      best_time = written;
    }
  }
  return best;
}

}  // namespace ropes::crl
