#pragma once
/// @file main_job.hpp
/// The ROPES main job on one experiment config, as `ropes-run` runs it, into one directory
/// OUT:
///   1 generate  the training set of the dataset config the experiment config names,
///               OUT/train-data (ropes_sim's generator)
///   2 train     AE1, one LDR per joint, AE2 with the score-sparsity loss, OUT/run
///               (ropes_crl's trainer)
///   3 evaluate  the suites (suites.hpp) on test sets generated into OUT/test-data, with
///               the supervised baselines; OUT/report/results.json, results.md, report.html
///               and calibration.json
/// OUT/ropes-run.json records the finished stages: called again after an interruption, the
/// job keeps them, generation and training resume inside themselves (shards, checkpoints),
/// and evaluation runs again when asked for with other evaluation arguments. Another
/// config, seed, data seed or dataset config in the same OUT is refused, naming it.
///
/// Part of ropes_eval's pipeline library (`ropes_eval::pipeline`).
#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>

#include "ropes_eval/suites.hpp"

namespace ropes::eval {

struct MainJobOptions {
  std::string config;           ///< an experiment config file or installed name (1c-small)
  std::filesystem::path out;    ///< empty: runs/<the config's name>
  std::uint64_t seed = 0;       ///< the training seed
  std::uint64_t data_seed = 0;  ///< the training set's seed (the test sets take + 1)
  std::string dataset_config;   ///< empty: the experiment config's dataset.config
  int threads = 1;              ///< 1..256; every count gives the same bytes
  bool progress_bar = false;    ///< training draws a bar on stderr (else it logs lines)
  /// Called at every metrics record of the training (from the training threads, one call at
  /// a time; may be empty); what it throws stops the job there, and the run keeps its last
  /// checkpoints (a later call resumes). What the Python bindings stop a job with.
  std::function<void()> on_training_record;
  /// The evaluation; by default the suites id, ood and occlusion. Its out, cache, data,
  /// test_seed and threads are the job's (OUT/report, OUT/test-data, generated, data_seed
  /// + 1, threads).
  SuiteOptions suites = [] {
    SuiteOptions s;
    s.suites = {"id", "ood", "occlusion"};
    return s;
  }();
};

struct MainJobResult {
  std::filesystem::path dir, train_data, run_dir, report_dir, state_file;
  std::string table;       ///< the per-joint table beside the paper's numbers
  bool evaluated = false;  ///< by this call (false: it had been, with the same arguments)
};

/// Runs (or resumes) the job. `log` gets progress lines with their stage (1 generate,
/// 2 train, 3 evaluate); may be empty. Throws std::invalid_argument for options out of range
/// or an unknown dataset config, core::ConfigError for an unknown or invalid experiment
/// config, core::FileFormatError for one that is not JSON (all before anything is written),
/// std::runtime_error for an OUT that
/// holds another job or a symbolic link where the job writes; errors of the stages pass
/// through.
MainJobResult run_main_job(const MainJobOptions& options,
                           const std::function<void(int stage, const std::string& line)>& log = {});

}  // namespace ropes::eval
