#include "ropes_eval/evaluation_report.hpp"

#include <ropes_core/file_format_error.hpp>

#include <cmath>
#include <fstream>
#include <limits>
#include <sstream>

#include "json_file.hpp"
#include "ropes_eval/supervised.hpp"
#include "text_format.hpp"

namespace ropes::eval {

namespace fs = std::filesystem;
using detail::difference;
using detail::fmt;
using detail::index_of;
using detail::plus_minus;
using detail::table_columns;

namespace {

const double kNan = std::numeric_limits<double>::quiet_NaN();

std::string patch_label(std::int64_t occlusion) {
  return occlusion > 0 ? std::to_string(occlusion) : "--";
}

// the paper's appendix MSE of `joint` for (distribution, patch), NaN where it has none
double paper_mse(const nlohmann::json& appendix, const std::string& distribution,
                 std::int64_t occlusion, const std::string& joint) {
  const std::string patch = occlusion > 0 ? std::to_string(occlusion) : "none";
  const nlohmann::json::json_pointer p("/" + distribution + "/" + patch + "/" + joint);
  return appendix.is_object() && appendix.contains(p) && appendix[p].is_number()
             ? appendix[p].get<double>()
             : kNan;
}

const MethodSummary* method(const RunEvaluation& ev, const std::string& name) {
  for (const MethodSummary& m : ev.methods)
    if (m.method == name)
      return &m;
  return nullptr;
}

}  // namespace

nlohmann::json paper_suite_numbers(const std::string& setting, const fs::path& paper_results) {
  const fs::path file = paper_results.empty() ? installed_paper_results() : paper_results;
  const nlohmann::json paper = core::read_json_file_if_present(file);
  if (paper.is_discarded())
    throw core::FileFormatError(file.string() + ": cannot be read as JSON");
  nlohmann::json out = {
      {"appendix", nullptr}, {"table1_occlusion", nullptr}, {"robopepp", nullptr}};
  const nlohmann::json::json_pointer a("/appendix/mse/" + setting),
      t("/table1_occlusion/" + setting), r("/robopepp/mse/" + setting);
  if (paper.contains(a))
    out["appendix"] = paper[a];
  if (paper.contains(t))
    out["table1_occlusion"] = paper[t];
  if (paper.contains(r))
    out["robopepp"] = paper[r];
  return out;
}

const SuiteResult* EvaluationReport::find(const std::string& name) const {
  for (const SuiteResult& s : suites)
    if (s.name == name)
      return &s;
  return nullptr;
}

nlohmann::json EvaluationReport::to_json() const {
  nlohmann::json j = {
      {"format", "ropes-eval-report"},     {"format_version", 1},
      {"suites", nlohmann::json::array()}, {"notes", notes},
      {"paper_appendix", paper_appendix},  {"paper_table1_occlusion", paper_table1_occlusion},
      {"paper_robopepp", paper_robopepp},  {"supervised", nlohmann::json::array()}};
  for (const SupervisedInfo& s : supervised)
    j["supervised"].push_back({{"fraction", s.fraction},
                               {"labels", s.labels},
                               {"steps", s.steps},
                               {"final_loss", s.final_loss}});
  if (!suites.empty()) {
    j["run"] = suites[0].evaluation.run_dir;
    j["config"] = suites[0].evaluation.config_name;
    j["setting"] = suites[0].evaluation.setting;
  }
  auto entry = [](const SuiteResult& s) {
    return nlohmann::json{{"name", s.name},
                          {"distribution", s.distribution},
                          {"occlusion", s.occlusion},
                          {"data_config", s.data_config},
                          {"results", s.evaluation.to_json()}};
  };
  for (const SuiteResult& s : suites)
    j["suites"].push_back(entry(s));
  j["occlusion_diagnostics"] = nlohmann::json::array();
  for (const SuiteResult& s : occlusion_diagnostics)
    j["occlusion_diagnostics"].push_back(entry(s));
  if (screen)
    j["screen"] = screen->to_json();
  return j;
}

std::string EvaluationReport::table() const {
  std::ostringstream out;
  const SuiteResult* id = find("id");
  if (id != nullptr)
    out << id->evaluation.table();
  out << "suites (ROPES, mean over the repeats): MCC / MSE rad^2 per joint\n";
  for (const SuiteResult& s : suites) {
    const MethodSummary& r = s.evaluation.methods[0];
    out << "  " << s.name << " (" << s.data_config << "):";
    for (std::size_t k = 0; k < s.evaluation.joints.size(); ++k)
      out << "  " << s.evaluation.joints[k] << " " << fmt(r.mean.mcc[k]) << " / "
          << fmt(r.mean.mse[k]);
    out << "\n";
  }
  for (const std::string& n : notes)
    out << "  note: " << n << "\n";
  if (screen)
    out << screen->table();
  return out.str();
}

std::vector<OcclusionDiagnosticRow> EvaluationReport::occlusion_rows() const {
  std::vector<OcclusionDiagnosticRow> rows;
  std::vector<const SuiteResult*> occluded;
  for (const std::vector<SuiteResult>* list : {&suites, &occlusion_diagnostics})
    for (const SuiteResult& s : *list)
      if (s.occlusion > 0)
        occluded.push_back(&s);
  for (const SuiteResult* s : occluded) {
    const RunEvaluation& ev = s->evaluation;
    for (const char* name : {"ropes", "ldr_logit", "lambda0_autoencoder", "supervised_100%"}) {
      const MethodSummary* m = method(ev, name);
      if (m == nullptr)
        continue;
      rows.push_back({s->name, name, "all", m->mean.mcc});
      if (!ev.occlusion_split)
        continue;
      const OcclusionSplit& sp = *ev.occlusion_split;
      for (std::size_t i = 0; i < sp.methods.size(); ++i)
        if (sp.methods[i] == name) {
          rows.push_back({s->name, name, "squares hide robot pixels", sp.mcc_hiding[i]});
          rows.push_back({s->name, name, "squares miss the robot", sp.mcc_missing[i]});
        }
    }
  }
  return rows;
}

std::vector<OcclusionSummary> EvaluationReport::occlusion_summaries() const {
  std::vector<OcclusionSummary> out;
  for (const std::vector<SuiteResult>* list : {&suites, &occlusion_diagnostics})
    for (const SuiteResult& s : *list) {
      if (s.occlusion <= 0)
        continue;
      const RunEvaluation& ev = s.evaluation;
      OcclusionSummary row{s.name, "", ev.code_shift, std::nullopt, std::nullopt};
      for (std::int64_t c : ev.occluded_cameras)
        row.cameras += (row.cameras.empty() ? "" : ", ") + std::to_string(c);
      if (row.cameras.empty())
        row.cameras = "all";
      if (ev.occlusion_split) {
        row.share_hiding = ev.occlusion_split->share_hiding;
        row.robot_hidden = ev.occlusion_split->robot_hidden;
      }
      out.push_back(std::move(row));
    }
  return out;
}

std::string EvaluationReport::occlusion_markdown() const {
  const std::vector<OcclusionDiagnosticRow> rows = occlusion_rows();
  if (rows.empty())
    return "";
  std::ostringstream out;
  out << "\n## Occlusion diagnostics: which stage breaks\n\n"
         "AE1's code shift: E|Y_occluded − Y_clean|² / E|Y_clean − mean|² over the test set's "
         "observational samples (0: the code does not move; 1: as far as a clean code lies "
         "from the mean code). Hiding: the share of samples whose squares cover at least one "
         "robot pixel (the robot's silhouette rendered from the sample's angles), and the mean "
         "share of the robot's pixels covered.\n\n"
         "| suite | occluded cameras | AE1 code shift | samples whose squares hide the robot | "
         "robot pixels hidden |\n| --- | --- | --- | --- | --- |\n";
  for (const OcclusionSummary& r : occlusion_summaries())
    out << "| " << r.suite << " | " << r.cameras << " | " << fmt(r.code_shift) << " | "
        << fmt(r.share_hiding) << " | " << fmt(r.robot_hidden) << " |\n";
  out << "\nMCC per joint (mean over the repeats) of the methods that tell the stages apart: "
         "ropes (AE1, LDRs, AE2), ldr_logit (AE1 and the LDRs, no AE2), lambda0_autoencoder "
         "(AE2 without the sparsity term) and supervised_100% (an encoder fitted with every "
         "label on clean codes: what AE1's code still holds). Where ldr_logit holds and ropes "
         "falls, AE2 is fragile; where supervised_100% falls too, AE1's code is.\n\n"
         "| suite | method | test samples |";
  const std::vector<std::string>& joints =
      (suites.empty() ? occlusion_diagnostics : suites).front().evaluation.joints;
  for (const std::string& j : joints)
    out << " " << j << " |";
  out << "\n| --- | --- | --- |";
  for (std::size_t k = 0; k < joints.size(); ++k)
    out << " --- |";
  out << "\n";
  for (const OcclusionDiagnosticRow& r : rows) {
    out << "| " << r.suite << " | " << r.method << " | " << r.samples << " |";
    for (double v : r.mcc)
      out << " " << fmt(v) << " |";
    out << "\n";
  }
  return out.str();
}

std::string EvaluationReport::markdown() const {
  std::ostringstream out;
  const SuiteResult* id = find("id");
  if (suites.empty())
    return "# ropes-eval\n\nNo suite was evaluated.\n";
  const RunEvaluation& first = (id != nullptr ? *id : suites[0]).evaluation;
  const std::vector<std::string> columns = table_columns(first.joints);
  if (id != nullptr) {
    out << id->evaluation.markdown();
    // Table 1's "occl." row: the id suite with 32 px squares
    const SuiteResult* occl = find("id occlusion 32");
    if (occl != nullptr) {
      const RunEvaluation& ev = occl->evaluation;
      const MethodSummary& r = ev.methods[0];
      out << "\n## Table 1's occlusion row (32 px squares on the id test set)\n\n| setup |";
      for (const std::string& c : columns)
        out << " " << c << " MCC | MSE |";
      out << "\n| --- |";
      for (std::size_t i = 0; i < columns.size(); ++i)
        out << " --- | --- |";
      out << "\n| this run (" << ev.setting << ", occl.) |";
      for (const std::string& c : columns) {
        const std::ptrdiff_t k = index_of(ev.joints, c);
        out << (k < 0 ? std::string(" -- | -- |")
                      : " " + plus_minus(r.mean.mcc[k], r.std.mcc[k]) + " | " +
                            plus_minus(r.mean.mse[k], r.std.mse[k]) + " |");
      }
      auto paper = [&](const std::string& c, const char* what) {
        const nlohmann::json::json_pointer p("/32/" + c + "/" + what);
        return paper_table1_occlusion.is_object() && paper_table1_occlusion.contains(p) &&
                       paper_table1_occlusion[p].is_number()
                   ? paper_table1_occlusion[p].get<double>()
                   : kNan;
      };
      out << "\n| the paper (" << ev.setting << ", occl.) |";
      for (const std::string& c : columns)
        out << " " << fmt(paper(c, "mcc")) << " | " << fmt(paper(c, "mse")) << " |";
      out << "\n| difference |";
      for (const std::string& c : columns) {
        const std::ptrdiff_t k = index_of(ev.joints, c);
        out << (k < 0 ? std::string(" -- | -- |")
                      : " " + difference(r.mean.mcc[k], paper(c, "mcc"), true) + " | " +
                            difference(r.mean.mse[k], paper(c, "mse"), false) + " |");
      }
      out << "\n";
    }
  }
  // the appendix table: MSE by distribution and patch size, the paper's row below ours
  out << "\n## The suites: MSE (rad²) per joint, laid out like the paper's appendix table\n\n"
         "Mean ± std over each suite's repeats; the paper's row (tab:mse_ablation_study) below "
         "ours where it has one, then the difference.\n\n| distribution | patch size | test set |";
  for (const std::string& c : columns)
    out << " " << c << " |";
  out << "\n| --- | --- | --- |";
  for (std::size_t i = 0; i < columns.size(); ++i)
    out << " --- |";
  out << "\n";
  for (const SuiteResult& s : suites) {
    const RunEvaluation& ev = s.evaluation;
    const MethodSummary& r = ev.methods[0];
    out << "| " << s.distribution << " | " << patch_label(s.occlusion) << " | " << s.data_config
        << " |";
    bool any_paper = false;
    for (const std::string& c : columns) {
      const std::ptrdiff_t k = index_of(ev.joints, c);
      out << " " << (k < 0 ? "--" : plus_minus(r.mean.mse[k], r.std.mse[k])) << " |";
      any_paper =
          any_paper || std::isfinite(paper_mse(paper_appendix, s.distribution, s.occlusion, c));
    }
    out << "\n";
    if (!any_paper)
      continue;
    out << "| the paper | " << patch_label(s.occlusion) << " | |";
    for (const std::string& c : columns)
      out << " " << fmt(paper_mse(paper_appendix, s.distribution, s.occlusion, c)) << " |";
    out << "\n| difference | | |";
    for (const std::string& c : columns) {
      const std::ptrdiff_t k = index_of(ev.joints, c);
      out << " "
          << (k < 0 ? "--"
                    : difference(r.mean.mse[k],
                                 paper_mse(paper_appendix, s.distribution, s.occlusion, c), false))
          << " |";
    }
    out << "\n";
  }
  // MCC of ROPES and of every baseline on every suite
  out << "\n## The suites: MCC of ROPES and the baselines\n\n"
         "Per joint, mean over the repeats. PCA's components have no pairing with the joints: "
         "its entries are the best assignment's MCC.\n\n| suite | method |";
  for (const std::string& j : first.joints)
    out << " " << j << " |";
  out << "\n| --- | --- |";
  for (std::size_t k = 0; k < first.joints.size(); ++k)
    out << " --- |";
  out << "\n";
  for (const SuiteResult& s : suites)
    for (const MethodSummary& one : s.evaluation.methods) {
      const MethodSummary* m = &one;
      const bool pca = m->method == "pca_of_code";
      out << "| " << s.name << " | " << m->method << " |";
      for (std::size_t k = 0; k < first.joints.size(); ++k)
        out << " "
            << plus_minus(pca ? m->mean.best_assignment_mcc[k] : m->mean.mcc[k],
                          pca ? m->std.best_assignment_mcc[k] : m->std.mcc[k])
            << " |";
      out << "\n";
    }
  // label efficiency: the supervised baselines on each suite against ROPES (and RoboPEPP)
  if (!supervised.empty()) {
    out << "\n## Label efficiency: a supervised encoder against ROPES\n\n"
           "The same encoder (AE1's, frozen, then AE2's, trained from scratch with labels) "
           "regressing the joints from a fraction of the training set's rows; MSE (rad²) of "
           "its estimate, no calibration, mean ± std over the repeats. ROPES: the affine "
           "calibration of its latent from the protocol's calibration samples. RoboPEPP: the "
           "paper's, at the same fractions of its training set.\n";
    for (const SuiteResult& s : suites) {
      if (s.occlusion > 0 && s.occlusion != 32)
        continue;
      const RunEvaluation& ev = s.evaluation;
      out << "\n### " << s.name << "\n\n| method | labels |";
      for (const std::string& j : ev.joints)
        out << " " << j << " |";
      out << "\n| --- | --- |";
      for (std::size_t k = 0; k < ev.joints.size(); ++k)
        out << " --- |";
      out << "\n";
      for (const SupervisedInfo& info : supervised) {
        const std::string name = supervised_method_name(info.fraction);
        const MethodSummary* m = method(ev, name);
        if (m == nullptr)
          continue;
        out << "| " << name << " | " << info.labels << " |";
        for (std::size_t k = 0; k < ev.joints.size(); ++k)
          out << " " << plus_minus(m->mean.mse[k], m->std.mse[k]) << " |";
        out << "\n";
        char pct[16];
        std::snprintf(pct, sizeof pct, "%g", 100.0 * info.fraction);
        const nlohmann::json::json_pointer p("/" + s.distribution + "/" + pct);
        if (s.occlusion == 0 && paper_robopepp.is_object() && paper_robopepp.contains(p)) {
          out << "| RoboPEPP (the paper) | " << pct << " % |";
          for (const std::string& j : ev.joints) {
            const nlohmann::json& v = paper_robopepp[p];
            out << " "
                << (v.is_object() && v.contains(j) && v[j].is_number() ? fmt(v[j].get<double>())
                                                                       : std::string("--"))
                << " |";
          }
          out << "\n";
        }
      }
      const MethodSummary& r = ev.methods[0];
      out << "| ROPES | 0 (calibration: " << ev.calibration_samples << ") |";
      for (std::size_t k = 0; k < ev.joints.size(); ++k)
        out << " " << plus_minus(r.mean.mse[k], r.std.mse[k]) << " |";
      out << "\n| labels a supervised encoder needs to match ROPES | |";
      for (std::size_t k = 0; k < ev.joints.size(); ++k) {
        std::string needed = "more than " + fmt(100.0 * supervised.back().fraction, 0) + " %";
        for (const SupervisedInfo& info : supervised) {
          const std::string name = supervised_method_name(info.fraction);
          const MethodSummary* m = method(ev, name);
          if (m != nullptr && m->mean.mse[k] <= r.mean.mse[k]) {
            char b[32];
            std::snprintf(b, sizeof b, "%g %%", 100.0 * info.fraction);
            needed = b;
            break;
          }
        }
        out << " " << needed << " |";
      }
      out << "\n";
    }
  }
  out << occlusion_markdown();
  if (!notes.empty()) {
    out << "\n## Suites not run\n\n";
    for (const std::string& n : notes)
      out << "- " << n << "\n";
  }
  if (screen)
    out << "\n" << screen->markdown();
  return out.str();
}

}  // namespace ropes::eval
