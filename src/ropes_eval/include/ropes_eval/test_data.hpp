#pragma once
/// @file test_data.hpp
/// The test data of the suites (suites.hpp): the dataset a suite needs, generated through
/// ropes_sim's generator into a cache directory and found there the next time. Part of
/// ropes_eval's pipeline library (`ropes_eval::pipeline`).
///
/// The cache entry of a dataset is CACHE/<config name>-seed<S>-<12 hex digits>, the digits
/// those of the SHA-256 of the config as the manifest records it plus the distribution file's
/// bytes: another config, distribution or seed is another entry, and the generator's own
/// resume (shard markers, generation.json) makes a complete entry cost nothing to reuse and
/// an interrupted one continue where it stopped.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

namespace ropes::eval {

/// Which test set: the training distribution (id), the paper's OOD observational table with
/// the ID interventions (ood), or the causal SEM over the joints (causal).
struct TestDataRequest {
  std::filesystem::path run_dir;    // the run whose training set names the config
  std::string distribution = "id";  // id, ood or causal
  std::int64_t min_observational = 0;
  std::uint64_t seed = 0;  // the test set's seed (not the training set's)
  std::filesystem::path cache;
  /// The training set's dataset config file when it is not installed (a robot of the user's
  /// own): its name must be the training set's, and its test_sets may name files relative to
  /// it. Empty: the installed config of the training set's name.
  std::filesystem::path train_config_file;
  int threads = 1;
  std::function<void(const std::string&)> log;  // progress lines; may be empty
};

struct TestData {
  std::filesystem::path dir;
  std::string config_name;            // e.g. small-2c_ood
  std::filesystem::path config_file;  // the dataset config it was made from (empty: --data)
  std::int64_t shards_written = 0;    // by this call (0: the cache had it)
};

/// The dataset config a suite uses for a run trained on the config `train_config` (the
/// installed one of that name, or `train_config_file` when given): the names its "test_sets"
/// field gives (small-2c: small-2c_ood, small-2c_causal; small-plus-2c also id: small-2c;
/// sim::DatasetConfig::test_sets); id without one -> the config itself. Empty when the
/// config names none for the
/// suite (the 1C configs: the paper defines no OOD or causal test set for one camera) or is
/// no installed config. Throws sim::ConfigError for a config that does not load.
std::string suite_config_name(const std::string& train_config, const std::string& distribution,
                              const std::filesystem::path& train_config_file = {});

/// The dataset config `name_or_path`: a file, or the installed ropes_sim config of that
/// name. Throws std::invalid_argument naming it when it is neither.
std::filesystem::path installed_dataset_config(const std::string& name_or_path);

/// Generates (or finds) the test set. Throws std::invalid_argument naming the run's training
/// set when its config is not an installed one or the installed one has another rig or image
/// size than the training set; errors of generate_dataset pass through.
TestData ensure_test_data(const TestDataRequest& request);

}  // namespace ropes::eval
