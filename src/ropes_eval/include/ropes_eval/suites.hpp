#pragma once
/// @file suites.hpp
/// The paper's evaluation suites of a trained run, as `ropes-eval --suite` and `ropes-run`
/// run them: every suite asked for, its test set generated into a cache (test_data.hpp) or
/// found there, the supervised baselines, the screening of AE1, and results.json, results.md,
/// report.html and (with the id suite) calibration.json in the report directory.
///
/// Part of ropes_eval's pipeline library (`ropes_eval::pipeline`), which links ropes_sim to
/// generate the test sets; `ropes_eval::ropes_eval` (the metrics) does not.
#include <cstdint>
#include <filesystem>
#include <functional>
#include <optional>
#include <string>
#include <vector>

#include "ropes_eval/evaluation_report.hpp"
#include "ropes_eval/run_evaluation.hpp"

namespace ropes::eval {

struct SuiteOptions {
  /// id, ood, causal and occlusion, each at most once (check_suites)
  std::vector<std::string> suites = {"id"};
  /// the id suite's test set; empty: generated from the training set's config
  std::filesystem::path data;
  /// the report directory; empty: crl::default_evaluation_dir(run)/report, beside the run.
  /// Never inside the run directory (std::invalid_argument).
  std::filesystem::path out;
  /// where test sets are generated; empty: default_test_data_cache()
  std::filesystem::path cache;
  /// the training set's dataset config file, when it is not installed (TestDataRequest::
  /// train_config_file); ropes-run passes the one it generated the training set from
  std::filesystem::path dataset_config;
  /// the test sets' seed; nullopt: the training set's + 1
  std::optional<std::uint64_t> test_seed;
  /// the occlusion suite's square sides in pixels (those larger than the image are left
  /// out with a note)
  std::vector<std::int64_t> occlusion_sizes = {16, 32, 64};
  /// the supervised baselines' fractions of labelled training rows, in (0, 1]
  std::vector<double> supervised = {0.01, 0.05, 0.10, 1.0};
  std::int64_t supervised_max_steps = 0;  ///< cap on their optimiser steps (0: none)
  int threads = 1;                        ///< for generating the test sets
  RunEvaluationOptions evaluation;        ///< the protocol (repeats, samples, seed, probe)
};

struct SuiteOutcome {
  EvaluationReport report;
  std::filesystem::path report_dir;  ///< where results.json, results.md, report.html are
};

/// std::invalid_argument ("'odd' is not a suite; expected id, ood, causal or occlusion")
/// unless every name is a suite.
void check_suites(const std::vector<std::string>& suites);

/// $ROPES_DATA_CACHE, else $XDG_CACHE_HOME/ropes/test-data, else ~/.cache/ropes/test-data;
/// std::invalid_argument when none of them is set.
std::filesystem::path default_test_data_cache();

/// Evaluates the run in `run_dir` on the suites and writes the report (see the file's
/// comment); progress lines go to `log` (may be empty). Every test set is found or generated
/// before the supervised baselines train. A suite the setting has none for (ood and causal
/// for one camera) becomes a note; std::invalid_argument when no suite asked for can run, for
/// a test seed equal to the training set's, an `out` inside the run directory or a bad
/// suite name. Errors of the run's files are core::FileFormatError naming the file.
SuiteOutcome run_suites(const std::filesystem::path& run_dir, const SuiteOptions& options,
                        const std::function<void(const std::string&)>& log = {});

}  // namespace ropes::eval
