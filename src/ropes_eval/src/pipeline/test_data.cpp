#include "ropes_eval/test_data.hpp"

#include <ropes_core/file_format_error.hpp>
#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_core/plain_name.hpp>
#include <ropes_core/sha256.hpp>
#include <ropes_crl/dataset_version.hpp>
#include <ropes_crl/run_directory.hpp>
#include <ropes_sim/dataset_config.hpp>
#include <ropes_sim/dataset_generator.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <fstream>
#include <sstream>
#include <stdexcept>
#include <system_error>
#include <vector>

namespace ropes::eval {

// ropes_crl reads datasets without linking the simulator, so it keeps its own number for the
// oldest sim_dataset_version it reads; this file sees both
static_assert(sim::kFirstVarianceReadingVersion == crl::kOldestSimDatasetVersion,
              "ropes_sim and ropes_crl disagree on the first sim_dataset_version of the "
              "variance reading");

namespace fs = std::filesystem;

namespace {

std::string read_text(const fs::path& p) {
  try {
    return core::read_text_file(p, core::kMaxJsonFileBytes);
  } catch (const core::FileFormatError& e) {
    throw std::invalid_argument(e.what());
  }
}

nlohmann::json read_json(const fs::path& p) {
  try {
    return core::read_json_file(p);
  } catch (const core::FileFormatError& e) {
    throw std::invalid_argument(e.what());
  }
}

// the installed config of that name (never a path: the name may come from a manifest)
fs::path installed_config(const std::string& name) {
  if (!core::is_plain_name(name))
    return {};
  const fs::path p = sim::installed_dataset_configs_dir() / (name + ".json");
  return core::is_regular_file(p) ? p : fs::path();
}

}  // namespace

fs::path installed_dataset_config(const std::string& name_or_path) {
  const fs::path p = sim::find_dataset_config(name_or_path);
  if (p.empty())
    throw std::invalid_argument("dataset config '" + name_or_path +
                                "' is neither a file nor an installed ropes_sim config (in " +
                                sim::installed_dataset_configs_dir().string() + ")");
  return p;
}

std::string suite_config_name(const std::string& train_config, const std::string& distribution,
                              const fs::path& train_config_file) {
  const fs::path file =
      train_config_file.empty() ? installed_config(train_config) : train_config_file;
  if (file.empty())
    return distribution == "id" ? train_config : "";
  const sim::DatasetConfig config = sim::DatasetConfig::load(file);
  const auto named = config.test_sets.find(distribution);
  if (named == config.test_sets.end())
    return distribution == "id" ? train_config : "";
  return named->second;
}

namespace {

// the config file of test set `name`: the training config's own file for its name, one
// relative to it (a name with a '/' or ending in .json), else the installed one
fs::path test_config_file(const std::string& name, const std::string& train_config,
                          const fs::path& train_config_file) {
  if (!train_config_file.empty()) {
    if (name == train_config)
      return train_config_file;
    if (name.find('/') != std::string::npos || fs::path(name).extension() == ".json") {
      const fs::path p = train_config_file.parent_path() / name;
      return core::is_regular_file(p) ? p : fs::path();
    }
  }
  return installed_config(name);
}

}  // namespace

TestData ensure_test_data(const TestDataRequest& request) {
  const crl::RunDirectory run = crl::RunDirectory::open(request.run_dir);
  const fs::path& train_dir = run.data_dir();
  const fs::path manifest = train_dir / "manifest.json";
  if (train_dir.empty() || !core::is_regular_file(manifest))
    throw std::invalid_argument(
        run.run_file().string() + ": its training set '" + train_dir.string() +
        "' has no manifest.json; the suites take their configs from it (or pass --data DIR)");
  // a run trained on a dataset of the old TN(mean, x) reading gets no test set of the new one
  crl::require_run_of_current_sim_dataset(run);
  const nlohmann::json meta = read_json(manifest).value("metadata", nlohmann::json::object());
  const std::string train_config =
      meta.contains("config") && meta["config"].is_object() ? meta["config"].value("name", "") : "";
  if (!request.train_config_file.empty()) {
    const sim::DatasetConfig given = sim::DatasetConfig::load(request.train_config_file);
    if (given.name != train_config)
      throw std::invalid_argument(request.train_config_file.string() + " is dataset config '" +
                                  given.name + "', but the run's training set (" +
                                  manifest.string() + ") was made from '" + train_config + "'");
  }
  const std::string name =
      suite_config_name(train_config, request.distribution, request.train_config_file);
  if (name.empty())
    throw std::invalid_argument(
        "no " + request.distribution + " test set is defined for '" + train_config +
        "' (its config names none in test_sets; the paper defines OOD and causal "
        "test sets for two cameras)");
  const fs::path file = test_config_file(name, train_config, request.train_config_file);
  if (file.empty())
    throw std::invalid_argument(
        manifest.string() + ": " +
        (request.distribution == "id"
             ? "the training set's config '" + train_config + "'"
             : "the " + request.distribution + " test set's config '" + name +
                   "' (test_sets of the training set's config '" + train_config + "')") +
        " is not an installed ropes_sim config; generate a test set with ropes-generate and "
        "pass it with --data DIR");
  sim::DatasetConfig config = sim::DatasetConfig::load(file);
  // the test set shows the robot as the training set did: the same rig and image size
  const nlohmann::json ours = nlohmann::json::parse(config.to_json());
  for (const char* field : {"rig", "image"})
    if (ours.value(field, nlohmann::json()) != meta["config"].value(field, nlohmann::json()))
      throw std::invalid_argument(manifest.string() + ": the training set's " + field +
                                  " differs from the installed config " + file.string() +
                                  "'s; pass a test set with --data DIR");
  config.anchors = std::max(config.anchors, request.min_observational);
  const std::string identity = config.to_json() + read_text(config.distribution);
  const std::string key = core::sha256_hex(identity.data(), identity.size()).substr(0, 12);
  TestData out;
  out.config_name = name;
  out.config_file = file;
  out.dir = request.cache / (name + "-seed" + std::to_string(request.seed) + "-" + key);
  sim::GenerateOptions options;
  options.out = out.dir;
  options.seed = request.seed;
  options.threads = request.threads;
  if (request.log)
    options.progress = [&](int done, int total, const std::string&) {
      request.log("generating " + name + " (seed " + std::to_string(request.seed) + "): shard " +
                  std::to_string(done) + "/" + std::to_string(total));
    };
  fs::create_directories(request.cache);
  const sim::GenerateResult result = sim::generate_dataset(config, options);
  if (!result.complete)
    throw std::runtime_error(out.dir.string() + ": the test set is not complete after generation");
  // the same robot as the training set, and for id the same distribution: a training set
  // made from a modified copy of an installed config is caught here
  const nlohmann::json test_meta =
      read_json(out.dir / "manifest.json").value("metadata", nlohmann::json::object());
  std::vector<std::string> fields = {"robot"};
  if (request.distribution == "id")
    fields.push_back("distribution");
  for (const std::string& f : fields)
    if (test_meta.value(f, nlohmann::json()) != meta.value(f, nlohmann::json()))
      throw std::invalid_argument(
          manifest.string() + ": the training set's " + f + " differs from that of the " +
          request.distribution + " test set made from the installed config " + file.string() +
          " (was the training set made from a modified copy?); pass a test set with --data DIR");
  out.shards_written = result.shards_written;
  return out;
}

}  // namespace ropes::eval
