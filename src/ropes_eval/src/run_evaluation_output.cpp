#include "ropes_eval/run_evaluation.hpp"

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <sstream>
#include <string>
#include <vector>

#include "json_file.hpp"
#include "text_format.hpp"

namespace ropes::eval {

using detail::difference;
using detail::fmt;
using detail::join;

// RunEvaluation's three forms: results.json, the console table, results.md

nlohmann::json RunEvaluation::to_json() const {
  const auto nums = detail::numbers_or_null;
  // null without an occlusion; code_shift, and the split when robot masks were given
  auto occlusion_json = [&]() -> nlohmann::json {
    if (occlusion <= 0)
      return nullptr;
    nlohmann::json j = {{"code_shift", nums({code_shift})[0]}, {"split", nullptr}};
    if (occlusion_split) {
      const OcclusionSplit& sp = *occlusion_split;
      nlohmann::json hiding = nlohmann::json::object(), missing = nlohmann::json::object();
      for (std::size_t m = 0; m < sp.methods.size(); ++m) {
        hiding[sp.methods[m]] = nums(sp.mcc_hiding[m]);
        missing[sp.methods[m]] = nums(sp.mcc_missing[m]);
      }
      j["split"] = {{"share_hiding_robot", sp.share_hiding},
                    {"robot_hidden", sp.robot_hidden},
                    {"mcc_hiding_robot", hiding},
                    {"mcc_missing_robot", missing}};
    }
    return j;
  };
  auto scores = [&](const MethodScores& m) {
    return nlohmann::json{{"mcc", nums(m.mcc)},
                          {"mse", nums(m.mse)},
                          {"spearman", nums(m.spearman)},
                          {"best_assignment_mcc", nums(m.best_assignment_mcc)},
                          {"mse_all_latents", nums(m.mse_all_latents)}};
  };
  nlohmann::json by_method = nlohmann::json::object();
  for (const MethodSummary& m : methods) {
    nlohmann::json j = scores(m.mean);
    const nlohmann::json sd = scores(m.std);
    for (auto it = sd.begin(); it != sd.end(); ++it)
      j[it.key() + "_std"] = it.value();
    j["repeats"] = nlohmann::json::array();
    for (const MethodScores& r : m.repeats) {
      nlohmann::json one = scores(r);
      one["best_assignment"] = r.best_assignment;
      j["repeats"].push_back(one);
    }
    by_method[m.method] = j;
  }
  return {{"format", "ropes-eval-results"},
          {"format_version", 2},
          {"run", run_dir},
          {"data", data_dir},
          {"config", config_name},
          {"setting", setting},
          {"dataset", dataset_id},
          {"train_dataset", train_dataset_id},
          {"joints", joints},
          {"extensions", extensions},
          {"provenance", provenance},
          {"provenance_differences", provenance_differences},
          {"protocol",
           {{"repeats", methods.empty() ? 0 : methods[0].repeats.size()},
            {"calibration_samples", calibration_samples},
            {"test_samples", test_samples},
            {"observational_samples", observational_samples},
            {"seed", seed},
            {"best_repeat", best_repeat},
            {"occlusion", occlusion},
            {"occlusion_seed", occlusion_seed},
            {"occluded_cameras", occluded_cameras}}},
          {"methods", by_method},
          {"occlusion_diagnostics", occlusion_json()},
          {"diagnostics",
           {{"probe_linear_mse", nums(probe_linear_mse)},
            {"probe_mlp_mse", nums(probe_mlp_mse)},
            {"angle_variance", nums(angle_variance)},
            {"ldr_held_out_accuracy", nums(ldr_accuracy)},
            {"ldr_bayes_accuracy", nums(bayes_accuracy)}}},
          {"paper", {{"mcc", nums(paper_mcc)}, {"mse", nums(paper_mse)}}},
          {"calibration", calibration.to_json()},
          {"notes",
           "each repeat draws calibration_samples and disjoint test_samples from the "
           "observational samples; a method's numbers are the mean over the repeats (*_std: the "
           "standard deviation, n - 1; repeats: each one). mcc: |Pearson| of latent k and joint k "
           "on the test samples; mse: rad^2 of the affine fit of joint k from latent k, fitted on "
           "the calibration samples, on the test samples; diagnostics: repeat 0's samples; "
           "spearman: |Spearman| of latent k and joint k; best_assignment_mcc: |Pearson| of joint "
           "k and the latent best_assignment[k] that a maximum-weight matching of joints to "
           "distinct latents on the |Pearson| matrix gives it; mse_all_latents: rad^2 of the "
           "affine fit of joint k from every latent of the method"}};
}

std::string RunEvaluation::table() const {
  const std::size_t reps = methods.empty() ? 0 : methods[0].repeats.size();
  auto pm = [](double mean, double sd) { return fmt(mean) + " ± " + fmt(sd); };
  std::ostringstream out;
  out << "ropes-eval: " << config_name << ", " << reps << " repeats of " << calibration_samples
      << " calibration and " << test_samples << " test samples (of " << observational_samples
      << " observational, dataset " << dataset_id.substr(0, 12) << "); mean ± std\n";
  if (!provenance_differences.empty())
    out << "note: trained under another build than this one (" << join(provenance_differences)
        << "): the numbers compare to rounding, not bit for bit\n";
  out << "| joint | MCC | MSE rad^2 | paper MCC | paper MSE | best-assignment MCC / Spearman | "
         "MSE from all latents |";
  // PCA's components have no pairing with the joints: its column is the best assignment's
  auto matched = [](const MethodSummary& m) { return m.method == "pca_of_code"; };
  for (std::size_t m = 1; m < methods.size(); ++m)
    out << " " << methods[m].method << (matched(methods[m]) ? " best-assignment" : "") << " MCC |";
  out << " probe MSE linear / MLP | angle var | LDR acc / Bayes |\n";
  out << "| --- | --- | --- | --- | --- | --- | --- |";
  for (std::size_t m = 1; m < methods.size(); ++m)
    out << " --- |";
  out << " --- | --- | --- |\n";
  for (std::size_t k = 0; k < joints.size(); ++k) {
    const MethodSummary& r = methods[0];
    // repeats whose best assignment gives joint k another latent than latent k
    std::size_t other = 0;
    for (const MethodScores& one : r.repeats)
      other +=
          k < one.best_assignment.size() && one.best_assignment[k] != static_cast<std::int64_t>(k)
              ? 1
              : 0;
    out << "| " << joints[k] << " | " << pm(r.mean.mcc[k], r.std.mcc[k]) << " | "
        << pm(r.mean.mse[k], r.std.mse[k]) << " | " << fmt(paper_mcc[k]) << " | "
        << fmt(paper_mse[k]) << " | " << fmt(r.mean.best_assignment_mcc[k])
        << (other > 0
                ? " (another latent in " + std::to_string(other) + "/" + std::to_string(reps) + ")"
                : std::string())
        << " / " << fmt(r.mean.spearman[k]) << " | " << fmt(r.mean.mse_all_latents[k]) << " |";
    for (std::size_t m = 1; m < methods.size(); ++m) {
      const MethodSummary& b = methods[m];
      out << " "
          << (matched(b) ? pm(b.mean.best_assignment_mcc[k], b.std.best_assignment_mcc[k])
                         : pm(b.mean.mcc[k], b.std.mcc[k]))
          << " |";
    }
    out << " " << fmt(probe_linear_mse[k], 4) << " / "
        << (probe_mlp_mse.empty() ? "-" : fmt(probe_mlp_mse[k], 4)) << " | "
        << fmt(angle_variance[k]) << " | " << fmt(ldr_accuracy[k]) << " / "
        << fmt(bayes_accuracy[k]) << " |\n";
  }
  return out.str();
}

std::string RunEvaluation::markdown() const {
  const std::size_t reps = methods.empty() ? 0 : methods[0].repeats.size();
  const MethodSummary& r = methods[0];
  auto pm = [](double mean, double sd) { return fmt(mean) + " ± " + fmt(sd); };
  // the paper's Table 1 has Joint 1 .. Joint 6 of the Panda; a run of other joints gets its own
  const std::vector<std::string> columns = detail::table_columns(joints);
  auto index_of = [&](const std::string& c) { return detail::index_of(joints, c); };
  std::ostringstream out;
  out << "# ropes-eval: " << config_name << "\n\n"
      << "- run: `" << run_dir << "`\n"
      << "- test data: `" << data_dir << "` (dataset " << dataset_id << "); trained on dataset "
      << train_dataset_id << "\n"
      << "- protocol: " << reps << " repeats, each " << calibration_samples << " calibration and "
      << test_samples << " disjoint test samples drawn from the " << observational_samples
      << " observational samples (seed " << seed << "); mean ± std over the repeats; MSE in rad²\n";
  for (const std::string& e : extensions)
    out << "- **extension, not the paper's method**: " << e << "\n";
  if (provenance.is_object() && provenance.contains("evaluation") &&
      provenance["evaluation"].is_object()) {
    const nlohmann::json& built = provenance["evaluation"];
    out << "- build: " << built.value("isa_level", "?") << ", " << built.value("compiler", "?")
        << ", Eigen " << built.value("eigen", "?") << ", revision " << built.value("revision", "?")
        << ", " << built.value("threads", 0) << " thread(s)\n";
  }
  if (!provenance_differences.empty())
    out << "- **trained under another build** (" << join(provenance_differences)
        << "): the numbers compare to rounding, not bit for bit\n";
  out << "\n";

  out << "## MCC and MSE, laid out like the paper's Table 1\n\n| setup |";
  for (const std::string& c : columns)
    out << " " << c << " MCC | MSE |";
  out << "\n| --- |";
  for (std::size_t i = 0; i < columns.size(); ++i)
    out << " --- | --- |";
  out << "\n| this run (" << setting << ") |";
  for (const std::string& c : columns) {
    const std::ptrdiff_t k = index_of(c);
    if (k < 0)
      out << " -- | -- |";
    else
      out << " " << pm(r.mean.mcc[k], r.std.mcc[k]) << " | " << pm(r.mean.mse[k], r.std.mse[k])
          << " |";
  }
  out << "\n| the paper (" << setting << ") |";
  for (const std::string& c : columns) {
    const std::ptrdiff_t k = index_of(c);
    out << " " << (k < 0 ? "--" : fmt(paper_mcc[k])) << " | " << (k < 0 ? "--" : fmt(paper_mse[k]))
        << " |";
  }
  out << "\n| difference |";
  for (const std::string& c : columns) {
    const std::ptrdiff_t k = index_of(c);
    if (k < 0)
      out << " -- | -- |";
    else
      out << " " << difference(r.mean.mcc[k], paper_mcc[k], true) << " | "
          << difference(r.mean.mse[k], paper_mse[k], false) << " |";
  }
  out << "\n\n## Baselines: MCC per joint\n\n"
         "PCA's components have no pairing with the joints: its row is the best assignment's "
         "MCC. The best-assignment MCC matches joints to distinct latents.\n\n| method |";
  for (const std::string& j : joints)
    out << " " << j << " |";
  out << "\n| --- |";
  for (std::size_t k = 0; k < joints.size(); ++k)
    out << " --- |";
  out << "\n";
  auto row = [&](const std::string& label, const std::vector<double>& mean,
                 const std::vector<double>& sd) {
    out << "| " << label << " |";
    for (std::size_t k = 0; k < joints.size(); ++k)
      out << " " << pm(mean[k], sd[k]) << " |";
    out << "\n";
  };
  row("ROPES", r.mean.mcc, r.std.mcc);
  row("ROPES, best assignment", r.mean.best_assignment_mcc, r.std.best_assignment_mcc);
  row("ROPES, Spearman", r.mean.spearman, r.std.spearman);
  for (std::size_t m = 1; m < methods.size(); ++m) {
    const MethodSummary& b = methods[m];
    if (b.method == "pca_of_code")
      row("PCA of AE1's code, best assignment", b.mean.best_assignment_mcc,
          b.std.best_assignment_mcc);
    else
      row(b.method == "lambda0_autoencoder" ? "λ = 0 autoencoder"
          : b.method == "ldr_logit"         ? "LDR logit"
                                            : b.method,
          b.mean.mcc, b.std.mcc);
  }
  out << "\n## Diagnostics (repeat 0's samples)\n\n"
         "| joint | probe MSE from Y, linear | MLP | angle variance | LDR held-out accuracy | "
         "Bayes accuracy | MSE from all of ROPES' latents (mean of the repeats) |\n"
         "| --- | --- | --- | --- | --- | --- | --- |\n";
  for (std::size_t k = 0; k < joints.size(); ++k)
    out << "| " << joints[k] << " | " << fmt(probe_linear_mse[k], 4) << " | "
        << (probe_mlp_mse.empty() ? "-" : fmt(probe_mlp_mse[k], 4)) << " | "
        << fmt(angle_variance[k]) << " | " << fmt(ldr_accuracy[k]) << " | "
        << fmt(bayes_accuracy[k]) << " | " << fmt(r.mean.mse_all_latents[k]) << " |\n";
  return out.str();
}

}  // namespace ropes::eval
