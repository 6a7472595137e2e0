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

/// One row of the occlusion diagnostics (results.md, report.html): a method's MCC per joint
/// (the suite's joints) on an occluded suite's test samples, all of them or one group of
/// OcclusionSplit.
struct OcclusionDiagnosticRow {
  std::string suite, method;
  std::string samples;  ///< "all", "squares hide robot pixels" or "squares miss the robot"
  std::vector<double> mcc;
};

/// One occluded suite's summary (results.md, report.html): which cameras carry the squares
/// ("all" or their indices, e.g. "0"), AE1's code shift (RunEvaluation::code_shift) and, where
/// the suite has OcclusionSplit, the share of samples whose squares hide robot pixels and the
/// mean share of the robot's pixels hidden.
struct OcclusionSummary {
  std::string suite, cameras;
  double code_shift = 0;
  std::optional<double> share_hiding, robot_hidden;
};

struct EvaluationReport {
  std::vector<SuiteResult> suites;
  /// Occluded suites that are diagnostics, not the paper's test, kept out of the suites'
  /// tables: with two cameras, the id test set with the squares in one camera only
  /// (RunEvaluationOptions::occluded_cameras), named e.g. "id occlusion 32, cam0 only".
  std::vector<SuiteResult> occlusion_diagnostics;
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
  /// RunEvaluation::to_json()}], "occlusion_diagnostics": [the same for those suites],
  /// "notes", "paper_appendix", "screen": Screening::to_json() (when screened)}.
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
  /// Every occluded suite (the paper's, then the diagnostics) and, per suite, the methods
  /// that tell the stages apart — ropes, ldr_logit (AE1 + LDR, no AE2), lambda0_autoencoder
  /// and the supervised encoder with every label (AE1's code alone) — on all test samples
  /// and, where the suite has OcclusionSplit, on each group.
  std::vector<OcclusionDiagnosticRow> occlusion_rows() const;
  /// One summary per occluded suite, the paper's suites first, then the diagnostics.
  std::vector<OcclusionSummary> occlusion_summaries() const;
  /// The occluded suites' summaries as a markdown section ("" without an occluded suite):
  /// AE1's code shift, the share of samples whose squares hide the robot, and
  /// occlusion_rows().
  std::string occlusion_markdown() const;
};

/// The paper's appendix numbers for `setting` from paper_results.json (empty: the installed
/// one): {"appendix": {...}, "table1_occlusion": {...}, "robopepp": {...}}, each null when
/// the paper has none.
nlohmann::json paper_suite_numbers(const std::string& setting,
                                   const std::filesystem::path& paper_results = {});

}  // namespace ropes::eval
