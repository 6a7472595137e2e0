#include "ropes_eval/screening.hpp"

#include <ropes_core/dataset.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_core/npy.hpp>
#include <ropes_crl/dataset_version.hpp>
#include <ropes_crl/run_directory.hpp>

#include <Eigen/Core>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <limits>
#include <set>
#include <sstream>
#include <stdexcept>

#include "json_file.hpp"
#include "ropes_eval/probes.hpp"
#include "ropes_eval/run_evaluation.hpp"
#include "text_format.hpp"

namespace ropes::eval {

namespace fs = std::filesystem;
using detail::fmt;

namespace {

constexpr double kNaN = std::numeric_limits<double>::quiet_NaN();

// the variance of `angles`' column k over `rows` (divided by n, as the probes' MSE is)
double variance_of(const Eigen::MatrixXd& angles, Eigen::Index k,
                   const std::vector<Eigen::Index>& rows) {
  double mean = 0, ss = 0;
  for (Eigen::Index r : rows)
    mean += angles(r, k) / static_cast<double>(rows.size());
  for (Eigen::Index r : rows)
    ss += (angles(r, k) - mean) * (angles(r, k) - mean) / static_cast<double>(rows.size());
  return ss;
}

}  // namespace

Screening screen_run(const fs::path& run_dir, const ScreeningOptions& options) {
  if (!(options.test_fraction > 0 && options.test_fraction < 1))
    throw std::invalid_argument("screen_run: test_fraction is " +
                                std::to_string(options.test_fraction) + "; expected 0 < f < 1");
  if (options.probe_steps < 0)
    throw std::invalid_argument("screen_run: probe_steps is " +
                                std::to_string(options.probe_steps) + "; expected >= 0");
  Screening s;
  s.run_dir = run_dir.string();
  s.seed = options.seed;
  s.probe_steps = options.probe_steps;
  const crl::RunDirectory run = crl::RunDirectory::open(run_dir);
  s.joints = run.joints();
  s.config_name = run.config().name;
  s.dataset_id = run.dataset_id();

  // the codes of stage 1, row for row with the training set
  const fs::path codes_path = run.codes_file();
  if (!core::is_regular_file(codes_path))
    throw core::FileFormatError(codes_path.string() +
                                " is missing: AE1 has not finished (ropes-train --stages ae1 "
                                "writes it)");
  const core::NpyArray codes = core::read_npy(codes_path);
  const fs::path& data_dir = run.data_dir();
  const core::DatasetReader reader = core::DatasetReader::open(data_dir);
  crl::require_current_sim_dataset(reader);
  if (codes.dtype != core::DType::kF32 || codes.shape.size() != 4 ||
      codes.shape[0] != reader.rows())
    throw core::FileFormatError(
        codes_path.string() + ": expected f32 [" + std::to_string(reader.rows()) +
        ", C, H, W], the codes of every row of the training set " + data_dir.string());
  const std::int64_t rows = codes.shape[0], per = codes.shape[1] * codes.shape[2] * codes.shape[3];

  // the run's joints among the training set's angle columns
  const core::ColumnSpec &angles_column = reader.column("angles"),
                         &anchor_column = reader.column("anchor");
  if (angles_column.dtype != core::DType::kF32 || angles_column.row_shape.size() != 1 ||
      anchor_column.dtype != core::DType::kI64 || !anchor_column.row_shape.empty())
    throw core::FileFormatError((data_dir / "manifest.json").string() +
                                ": expected the columns angles f32 [n, joints] and anchor i64 [n]");
  const nlohmann::json& names = reader.metadata_at("/joint_names");
  const std::int64_t width = angles_column.row_shape[0];
  std::vector<std::int64_t> column;
  for (const std::string& j : s.joints) {
    std::int64_t at = -1;
    for (std::size_t i = 0; i < names.size(); ++i)
      if (names[i] == j)
        at = static_cast<std::int64_t>(i);
    if (at < 0 || at >= width)
      throw core::FileFormatError((data_dir / "manifest.json").string() +
                                  ": no angle column for '" + j + "'");
    column.push_back(at);
  }

  // Y [rows, C*H*W] and the angles [rows, J], in double
  const std::int64_t jn = static_cast<std::int64_t>(s.joints.size());
  Eigen::MatrixXd y(rows, per), angles(rows, jn);
  for (std::int64_t r = 0; r < rows; ++r)
    for (std::int64_t c = 0; c < per; ++c) {
      float v;
      std::memcpy(&v, codes.data.data() + (r * per + c) * 4, 4);
      y(r, c) = v;
    }
  const core::NpyArray angle_rows = reader.read_rows("angles", 0, rows);
  for (std::int64_t r = 0; r < rows; ++r)
    for (std::int64_t k = 0; k < jn; ++k) {
      float v;
      std::memcpy(
          &v, angle_rows.data.data() + (r * width + column[static_cast<std::size_t>(k)]) * 4, 4);
      angles(r, k) = v;
    }

  // the split by anchor: every regime of an anchor on one side
  const core::NpyArray anchor_rows = reader.read_rows("anchor", 0, rows);
  std::vector<std::int64_t> anchor(static_cast<std::size_t>(rows));
  std::memcpy(anchor.data(), anchor_rows.data.data(), static_cast<std::size_t>(rows) * 8);
  std::vector<std::int64_t> distinct(anchor.begin(), anchor.end());
  std::sort(distinct.begin(), distinct.end());
  distinct.erase(std::unique(distinct.begin(), distinct.end()), distinct.end());
  const std::int64_t anchors = static_cast<std::int64_t>(distinct.size());
  if (anchors < 2)
    throw std::invalid_argument(data_dir.string() + ": " + std::to_string(anchors) +
                                " anchor(s); screening holds some out, so it needs at least 2");
  const std::int64_t held = std::clamp<std::int64_t>(
      std::llround(options.test_fraction * static_cast<double>(anchors)), 1, anchors - 1);
  const std::vector<std::int64_t> order = core::shuffled_indices(anchors, options.seed, 0);
  std::set<std::int64_t> test_anchor;
  for (std::int64_t i = 0; i < held; ++i)
    test_anchor.insert(distinct[static_cast<std::size_t>(order[static_cast<std::size_t>(i)])]);
  std::vector<Eigen::Index> train, test;
  for (std::int64_t r = 0; r < rows; ++r)
    (test_anchor.count(anchor[static_cast<std::size_t>(r)]) ? test : train).push_back(r);
  s.train_rows = static_cast<std::int64_t>(train.size());
  s.test_rows = static_cast<std::int64_t>(test.size());
  s.train_anchors = anchors - held;
  s.test_anchors = held;

  // the probes and what they explain of each joint's variance on the held-out anchors
  s.probe_linear_mse = detail::linear_probe(y, angles, train, test);
  if (options.probe_steps > 0)
    s.probe_mlp_mse = detail::mlp_probe(y, angles, train, test, options.probe_steps, options.seed);
  for (std::int64_t k = 0; k < jn; ++k) {
    const double v = variance_of(angles, k, test);
    s.angle_variance.push_back(v);
    s.probe_linear_r2.push_back(v > 0 ? 1 - s.probe_linear_mse[static_cast<std::size_t>(k)] / v
                                      : kNaN);
    if (!s.probe_mlp_mse.empty())
      s.probe_mlp_r2.push_back(v > 0 ? 1 - s.probe_mlp_mse[static_cast<std::size_t>(k)] / v : kNaN);
  }

  // the LDRs of stage 2, as the trainer recorded them
  for (const std::string& j : s.joints) {
    const std::optional<crl::LdrRecord> l = run.ldr(j);
    s.ldr_accuracy.push_back(l ? l->held_out_accuracy : kNaN);
    s.bayes_accuracy.push_back(l ? l->bayes_accuracy : kNaN);
  }
  return s;
}

nlohmann::json Screening::to_json() const {
  const auto nums = detail::numbers_or_null;
  return {{"format", "ropes-eval-screen"},
          {"format_version", 1},
          {"run", run_dir},
          {"config", config_name},
          {"dataset", dataset_id},
          {"seed", seed},
          {"probe_steps", probe_steps},
          {"split",
           {{"train_anchors", train_anchors},
            {"test_anchors", test_anchors},
            {"train_rows", train_rows},
            {"test_rows", test_rows}}},
          {"joints", joints},
          {"angle_variance", nums(angle_variance)},
          {"probe_linear_mse", nums(probe_linear_mse)},
          {"probe_linear_r2", nums(probe_linear_r2)},
          {"probe_mlp_mse", nums(probe_mlp_mse)},
          {"probe_mlp_r2", nums(probe_mlp_r2)},
          {"ldr_accuracy", nums(ldr_accuracy)},
          {"bayes_accuracy", nums(bayes_accuracy)}};
}

std::string Screening::table() const {
  std::ostringstream out;
  out << "AE1 screening of " << (config_name.empty() ? run_dir : config_name) << ": probes from "
      << "AE1's code fitted on " << train_anchors << " training anchors (" << train_rows
      << " rows), scored on " << test_anchors << " held-out anchors (" << test_rows << " rows)\n";
  out << "| joint | probe R^2 MLP | probe R^2 linear | probe MSE MLP / linear | angle var | LDR "
         "acc / Bayes |\n| --- | --- | --- | --- | --- | --- |\n";
  for (std::size_t k = 0; k < joints.size(); ++k) {
    const double mlp_r2 = probe_mlp_r2.empty() ? kNaN : probe_mlp_r2[k];
    const double mlp_mse = probe_mlp_mse.empty() ? kNaN : probe_mlp_mse[k];
    out << "| " << joints[k] << " | " << fmt(mlp_r2) << " | " << fmt(probe_linear_r2[k]) << " | "
        << fmt(mlp_mse, 4) << " / " << fmt(probe_linear_mse[k], 4) << " | "
        << fmt(angle_variance[k]) << " | " << fmt(ldr_accuracy[k]) << " / "
        << fmt(bayes_accuracy[k]) << " |\n";
  }
  return out.str();
}

std::string Screening::markdown() const {
  return "## AE1 screening: what its code holds of each joint\n\n"
         "Supervised probes from AE1's code to each joint (the training set's labels, used for "
         "this diagnostic only), fitted on some training anchors and scored on others: R^2 is "
         "the share of the joint's variance they explain. The LDR's held-out accuracy against "
         "the Bayes accuracy of its two interventions. Low values bound what ROPES can reach on "
         "a joint, whatever AE2 does.\n\n" +
         table() + "\n";
}

}  // namespace ropes::eval
