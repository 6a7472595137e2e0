#include "ropes_eval/evaluation_report.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <string>
#include <vector>

namespace ropes::eval {
namespace {

// a suite whose ROPES MSE of joint k is base + k / 100 (std 0.001) and MCC 0.9 - k / 100
SuiteResult suite(const std::string& distribution, std::int64_t occlusion, double base) {
  SuiteResult s;
  s.distribution = distribution;
  s.occlusion = occlusion;
  s.name = distribution + (occlusion > 0 ? " occlusion " + std::to_string(occlusion) : "");
  s.data_config = "small-2c" + std::string(distribution == "ood" ? "_ood" : "");
  RunEvaluation& ev = s.evaluation;
  ev.config_name = "2c-small";
  ev.setting = "2c";
  ev.joints = {"panda_joint2", "panda_joint4"};
  for (const char* name : {"ropes", "ldr_logit", "pca_of_code"}) {
    MethodSummary m;
    m.method = name;
    for (std::size_t k = 0; k < ev.joints.size(); ++k) {
      m.mean.mse.push_back(base + 0.01 * static_cast<double>(k));
      m.mean.mcc.push_back(0.9 - 0.01 * static_cast<double>(k));
      m.mean.best_assignment_mcc.push_back(0.5);
      m.mean.spearman.push_back(0.9);
      m.mean.mse_all_latents.push_back(base);
      m.std.mse.push_back(0.001);
      m.std.mcc.push_back(0.002);
      m.std.best_assignment_mcc.push_back(0.0);
      m.std.spearman.push_back(0.0);
      m.std.mse_all_latents.push_back(0.0);
    }
    m.repeats = {m.mean};
    ev.methods.push_back(m);
  }
  ev.probe_linear_mse = ev.probe_mlp_mse = ev.angle_variance = {0.1, 0.1};
  ev.ldr_accuracy = ev.bayes_accuracy = {0.9, 0.9};
  ev.paper_mcc = {0.979, 0.950};
  ev.paper_mse = {0.015, 0.035};
  return s;
}

// The installed paper numbers: the appendix's 2C rows (tab:mse_ablation_study) and Table 1's
// occlusion row, checked against the paper's text; none for 1C, which the appendix lacks
TEST(EvaluationReport, PaperSuiteNumbersAreTheAppendixTables) {
  const nlohmann::json two = paper_suite_numbers("2c");
  EXPECT_DOUBLE_EQ(two["appendix"]["ood"]["64"]["panda_joint4"].get<double>(), 0.227);
  EXPECT_DOUBLE_EQ(two["appendix"]["id"]["none"]["panda_joint3"].get<double>(), 0.217);
  EXPECT_DOUBLE_EQ(two["table1_occlusion"]["32"]["panda_joint6"]["mcc"].get<double>(), 0.768);
  EXPECT_DOUBLE_EQ(
      paper_suite_numbers("2c_causal")["appendix"]["ood"]["none"]["panda_joint1"].get<double>(),
      0.108);
  EXPECT_TRUE(paper_suite_numbers("1c")["appendix"].is_null());
}

// results.md: the appendix layout with the paper's row below ours and the difference marked;
// Table 1's occlusion row from the id suite at 32 px; the baselines on every suite; a suite
// that could not run is listed with its reason
TEST(EvaluationReport, MarkdownLaysTheSuitesOutLikeThePapersAppendix) {
  EvaluationReport r;
  r.suites = {suite("id", 0, 0.02), suite("id", 32, 0.03), suite("ood", 0, 0.01)};
  const nlohmann::json paper = paper_suite_numbers("2c");
  r.paper_appendix = paper["appendix"];
  r.paper_table1_occlusion = paper["table1_occlusion"];
  r.notes = {"causal: not asked"};
  const std::string md = r.markdown();
  auto has = [&](const std::string& text) {
    EXPECT_NE(md.find(text), std::string::npos) << "no '" << text << "' in\n" << md;
  };
  has("## The suites: MSE (rad²) per joint, laid out like the paper's appendix table");
  // id, no occlusion: ours 0.020 / 0.030 for joints 2 and 4 against the paper's 0.015 / 0.035
  has("| id | -- | small-2c | -- | 0.020 ± 0.001 | -- | 0.030 ± 0.001 | -- | -- |");
  has("| the paper | -- | | 0.083 | 0.015 | 0.217 | 0.035 | 0.198 | 0.080 |");
  has("| difference | | | -- | +0.005 **worse** | -- | -0.005 better | -- | -- |");
  // the OOD row and the paper's OOD row
  has("| ood | -- | small-2c_ood | -- | 0.010 ± 0.001 |");
  has("| the paper | -- | | 0.084 | 0.017 | 0.239 | 0.048 | 0.199 | 0.120 |");
  // Table 1's occlusion row: the paper's 2C indep. occl. MCC 0.964 for joint 2
  has("## Table 1's occlusion row");
  has("| the paper (2c, occl.) | 0.844 | 0.101 | 0.964 | 0.025 |");
  has("| this run (2c, occl.) | -- | -- | 0.900 ± 0.002 | 0.030 ± 0.001 |");
  has("| id occlusion 32 | ldr_logit | 0.900 ± 0.002 | 0.890 ± 0.002 |");
  has("| ood | pca_of_code | 0.500 ± 0.000 | 0.500 ± 0.000 |");
  has("- causal: not asked");
  const nlohmann::json j = r.to_json();
  EXPECT_EQ(j["format"], "ropes-eval-report");
  ASSERT_EQ(j["suites"].size(), 3u);
  EXPECT_EQ(j["suites"][1]["occlusion"], 32);
  EXPECT_EQ(j["suites"][2]["data_config"], "small-2c_ood");
  EXPECT_EQ(j["suites"][2]["results"]["methods"]["ropes"]["mse"][0], 0.01);
}

}  // namespace
}  // namespace ropes::eval
