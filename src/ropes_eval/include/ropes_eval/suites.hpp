#pragma once
// ropes-eval --suite and ropes-run's evaluation: every suite asked for, its test set
// generated or found in the cache, the supervised baselines, results.json, results.md and
// report.html in the report directory (private to ropes_eval's tools).
#include <ropes_eval/evaluation_report.hpp>
#include <ropes_eval/run_evaluation.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

#include "cli.hpp"

namespace ropes::eval::tools {

struct SuiteArgs {
  std::vector<std::string> suites;  // id, ood, causal, occlusion
  fs::path cache;                   // empty: default_cache()
  bool have_test_seed = false;
  std::uint64_t test_seed = 0;
  std::vector<std::int64_t> occlusion_sizes = {16, 32, 64};
  // fractions of labelled rows, ascending and each once (parse_supervised gives them so)
  std::vector<double> supervised = {0.01, 0.05, 0.10, 1.0};
  std::int64_t supervised_max_steps = 0;
};

struct SuiteOutcome {
  EvaluationReport report;
  fs::path report_dir;
};

/// UsageError unless every name is a suite.
void check_suites(const std::vector<std::string>& suites);

/// $ROPES_DATA_CACHE, else $XDG_CACHE_HOME/ropes/test-data, else ~/.cache/ropes/test-data.
fs::path default_cache();

/// Evaluates the run on the suites (`data`, when not empty, is the id test set) and writes
/// OUT (default RUN/report)/results.json, results.md, report.html and, with an id suite,
/// RUN/calibration.json; progress lines go to `log`. Every test set is found or generated
/// before the supervised baselines train; a suite the setting has none for becomes a note,
/// and std::invalid_argument when no suite asked for can run. UsageError for a test seed
/// equal to the training set's.
SuiteOutcome run_suites(const std::string& run_dir, const std::string& data, const std::string& out,
                        int threads, RunEvaluationOptions options, const SuiteArgs& args,
                        const std::function<void(const std::string&)>& log);

}  // namespace ropes::eval::tools
