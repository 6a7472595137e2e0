#pragma once
/// @file evaluation_report.hpp
/// EvaluationReport: one run evaluated on several suites (what `ropes-eval --suite` writes):
/// the in-distribution test set (id), the paper's OOD test set (ood), the causal one, and
/// each of them again with occluded images (white squares of 16, 32, 64 px). Each suite is a
/// RunEvaluation by the paper's protocol; the report lays them out like the paper's Table 1
/// (the id suite, and its 32 px occlusion as the "occl." row) and like its appendix table of
/// MSE per joint by distribution and patch size (tab:mse_ablation_study), the paper's numbers
/// in the row below ours and the difference marked.
#include <nlohmann/json.hpp>

#include <cstdint>
#include <optional>
#include <string>
#include <vector>

#include "ropes_eval/run_evaluation.hpp"
#include "ropes_eval/screening.hpp"

namespace ropes::eval {

struct SuiteResult {
  std::string name;            ///< e.g. "id", "ood", "id occlusion 32"
  std::string distribution;    ///< id, ood or causal
  std::int64_t occlusion = 0;  ///< the square's side in pixels (0: none)
  std::string data_config;     ///< the test set's dataset config (e.g. small-2c_ood)
  RunEvaluation evaluation;
};

/// One supervised baseline (supervised.hpp) the report's suites scored.
struct SupervisedInfo {
  double fraction = 0;  ///< of the training set's rows that were labelled
  std::int64_t labels = 0, steps = 0;
  double final_loss = 0;
};

struct EvaluationReport {
  std::vector<SuiteResult> suites;
  /// the supervised baselines, scored on every suite as methods "supervised_<p>%"
  std::vector<SupervisedInfo> supervised;
  /// the paper's RoboPEPP MSE by training-set fraction (paper_results.json "robopepp")
  nlohmann::json paper_robopepp;
  /// suites asked for that the setting has no test set for, each with the reason
  std::vector<std::string> notes;
  /// the paper's appendix numbers (paper_results.json "appendix"), for the setting
  nlohmann::json paper_appendix;
  /// the paper's Table 1 "occl." row (paper_results.json "table1_occlusion")
  nlohmann::json paper_table1_occlusion;
  /// what AE1's code holds of each joint and the LDRs' accuracy (screening.hpp), when screened
  std::optional<Screening> screen;

  /// results.json: {"format": "ropes-eval-report", "format_version": 1, "run", "config",
  /// "setting", "suites": [{"name", "distribution", "occlusion", "data_config", "results":
  /// RunEvaluation::to_json()}], "notes", "paper_appendix", "screen": Screening::to_json()
  /// (when screened)}.
  nlohmann::json to_json() const;
  /// results.md: the id suite's RunEvaluation::markdown(), the suites' MSE and MCC in the
  /// layout of the paper's appendix table, the baselines on every suite, and the label
  /// efficiency: the supervised baselines' MSE by fraction beside ROPES' and RoboPEPP's, and
  /// for each joint the smallest fraction whose supervised MSE is at most ROPES', and the
  /// AE1 screening.
  std::string markdown() const;
  /// The console table: the id suite's table, then one line per suite, then the screening.
  std::string table() const;
  /// The suite named `name`, or nullptr.
  const SuiteResult* find(const std::string& name) const;
};

/// The paper's appendix numbers for `setting` from paper_results.json (empty: the installed
/// one): {"appendix": {...}, "table1_occlusion": {...}, "robopepp": {...}}, each null when
/// the paper has none.
nlohmann::json paper_suite_numbers(const std::string& setting,
                                   const std::filesystem::path& paper_results = {});

}  // namespace ropes::eval
