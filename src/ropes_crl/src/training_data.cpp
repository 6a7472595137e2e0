#include "training_data.hpp"

#include <ropes_core/dataset.hpp>
#include <ropes_core/json_text.hpp>
#include <ropes_core/npy.hpp>
#include <ropes_nn/checkpoint.hpp>
#include <ropes_nn/ops.hpp>

#include <algorithm>
#include <cmath>
#include <cstring>
#include <map>
#include <set>
#include <stdexcept>

#include "ropes_crl/bayes_accuracy.hpp"
#include "ropes_crl/dataset_version.hpp"
#include "ropes_crl/sparsity_objective.hpp"
#include "run_files.hpp"

namespace ropes::crl::detail {

namespace fs = std::filesystem;

namespace {

void expect_column(const core::DatasetReader& reader, const fs::path& manifest,
                   const std::string& name, core::DType dtype) {
  bool found = false;
  for (const core::ColumnSpec& c : reader.columns())
    if (c.name == name) {
      found = true;
      if (c.dtype != dtype)
        throw std::invalid_argument(manifest.string() + ": column '" + name + "' is " +
                                    core::dtype_name(c.dtype) + ", expected " +
                                    core::dtype_name(dtype));
    }
  if (!found)
    throw std::invalid_argument(manifest.string() + ": no column '" + name +
                                "' (a ropes-generate dataset has images, angles, regime, anchor)");
}

template <class T>
std::vector<T> read_scalar_column(const core::DatasetReader& reader, const std::string& name) {
  const core::NpyArray a = reader.read_rows(name, 0, reader.rows());
  std::vector<T> out(static_cast<std::size_t>(reader.rows()));
  std::memcpy(out.data(), a.data.data(), out.size() * sizeof(T));
  return out;
}

}  // namespace

TrainingData TrainingData::open(const ExperimentConfig& config, const fs::path& dir,
                                std::uint64_t seed) {
  TrainingData d{dir, core::DatasetReader::open(dir), {}, 0, {}, {}, {}, {}, {}, {}, {}};
  const fs::path manifest = dir / "manifest.json";
  d.dataset_id = core::read_json_file(manifest).value("dataset", "");
  d.rows = d.reader.rows();
  require_current_sim_dataset(d.reader);  // never train on the old reading of TN(mean, x)
  d.reader.verify();  // a shard damaged after generation is refused, never trained on
  expect_column(d.reader, manifest, "images", core::DType::kU8);
  expect_column(d.reader, manifest, "regime", core::DType::kI32);
  expect_column(d.reader, manifest, "anchor", core::DType::kI64);
  const std::vector<std::int64_t> image = d.reader.column("images").row_shape;
  const std::vector<std::int64_t> want{config.cameras, config.image_size, config.image_size};
  if (image != want) {
    auto str = [](const std::vector<std::int64_t>& v) {
      std::string s = "[";
      for (std::size_t i = 0; i < v.size(); ++i)
        s += (i ? ", " : "") + std::to_string(v[i]);
      return s + "]";
    };
    throw std::invalid_argument(manifest.string() + ": images are " + str(image) +
                                " (cameras, height, width) a sample; config '" + config.name +
                                "' expects " + str(want));
  }
  // the regimes of each intervened joint
  const nlohmann::json& regimes =
      d.reader.metadata_at("/regimes", "regenerate the dataset with this ropes-generate");
  d.regime = read_scalar_column<std::int32_t>(d.reader, "regime");
  d.anchor = read_scalar_column<std::int64_t>(d.reader, "anchor");
  {  // each anchor's observational row: a regime without a joint is observational
    std::set<std::int32_t> observational;
    for (std::size_t r = 0; r < regimes.size(); ++r)
      if (regimes[r].is_object() && regimes[r].contains("joint") && regimes[r]["joint"].is_null())
        observational.insert(static_cast<std::int32_t>(r));
    std::map<std::int64_t, std::int64_t> row_of_anchor;
    for (std::int64_t r = 0; r < d.rows; ++r)
      if (observational.count(d.regime[static_cast<std::size_t>(r)]) != 0)
        row_of_anchor.emplace(d.anchor[static_cast<std::size_t>(r)], r);
    d.observational_row.assign(static_cast<std::size_t>(d.rows), -1);
    for (std::int64_t r = 0; r < d.rows; ++r) {
      const auto it = row_of_anchor.find(d.anchor[static_cast<std::size_t>(r)]);
      if (it != row_of_anchor.end())
        d.observational_row[static_cast<std::size_t>(r)] = it->second;
    }
  }
  const nlohmann::json& interventions =
      d.reader.metadata_at("/distribution/interventions", "the distribution's interventions");
  for (const std::string& joint : config.joints) {
    JointRegimes j;
    j.name = joint;
    bool one = false, two = false;
    for (std::size_t r = 0; r < regimes.size(); ++r) {
      const nlohmann::json& g = regimes[r];
      if (!g.contains("joint") || !g["joint"].is_string() || g["joint"] != joint)
        continue;
      if (g["intervention"] == 1) {
        j.regime1 = static_cast<std::int32_t>(r);
        one = true;
      } else if (g["intervention"] == 2) {
        j.regime2 = static_cast<std::int32_t>(r);
        two = true;
      }
    }
    if (!one || !two)
      throw std::invalid_argument(
          manifest.string() + ": joint '" + joint + "' of config '" + config.name +
          "' has no regimes with interventions 1 and 2 in metadata.regimes");
    for (std::int64_t r = 0; r < d.rows; ++r)
      if (d.regime[static_cast<std::size_t>(r)] == j.regime1 ||
          d.regime[static_cast<std::size_t>(r)] == j.regime2)
        j.rows.push_back(r);
    if (!interventions.contains(joint) || interventions[joint].size() != 2)
      throw std::invalid_argument(manifest.string() +
                                  ": metadata.distribution.interventions has no two entries for '" +
                                  joint + "'");
    j.bayes_accuracy = bayes_accuracy(
        truncated_normal_from_json(interventions[joint][0], "interventions." + joint + "[0]"),
        truncated_normal_from_json(interventions[joint][1], "interventions." + joint + "[1]"));
    d.joints.push_back(std::move(j));
  }
  // held-out anchors for the LDRs' early stopping: a seeded fraction of the distinct anchors
  std::set<std::int64_t> distinct(d.anchor.begin(), d.anchor.end());
  const std::vector<std::int64_t> all(distinct.begin(), distinct.end());
  const std::vector<std::int64_t> order = core::shuffled_indices(
      static_cast<std::int64_t>(all.size()), derive_seed(seed, "ldr.held_out"), 0);
  const std::size_t held = static_cast<std::size_t>(
      config.ldr_training.held_out_fraction * static_cast<double>(all.size()) + 0.5);
  for (std::size_t i = 0; i < held && i < order.size(); ++i)
    d.held_out_anchors.insert(all[static_cast<std::size_t>(order[i])]);
  const std::int64_t side = config.ae1.code_size();
  d.code_shape = {config.code_channels(), side, side};
  return d;
}

void TrainingData::load_codes(const fs::path& path) {
  const core::NpyArray a = core::read_npy(path);
  const std::vector<std::int64_t> want{rows, code_shape[0], code_shape[1], code_shape[2]};
  if (a.dtype != core::DType::kF32 || a.shape != want)
    throw core::FileFormatError(path.string() +
                                ": codes of another shape or dtype than this run's "
                                "(expected f32 [rows, C, side, side]); remove it to encode again");
  codes.resize(static_cast<std::size_t>(a.element_count()));
  std::memcpy(codes.data(), a.data.data(), codes.size() * 4);
}

std::vector<std::pair<std::int64_t, std::int64_t>> TrainingData::training_pairs(
    const JointRegimes& joint) const {
  std::map<std::int64_t, std::pair<std::int64_t, std::int64_t>> at;  // anchor -> (r1, r2)
  for (std::int64_t r : joint.rows) {
    if (held_out_anchor(r))
      continue;
    auto& p = at.try_emplace(anchor[static_cast<std::size_t>(r)], -1, -1).first->second;
    (regime[static_cast<std::size_t>(r)] == joint.regime1 ? p.first : p.second) = r;
  }
  std::vector<std::pair<std::int64_t, std::int64_t>> out;
  for (const auto& [a, p] : at)
    if (p.first >= 0 && p.second >= 0)
      out.push_back(p);
  return out;
}

nn::Tensor TrainingData::codes_of(const std::vector<std::int64_t>& picked) const {
  return gather_rows(codes, code_shape, picked);
}

nn::Tensor TrainingData::labels_of(const std::vector<std::int64_t>& picked,
                                   std::int32_t positive) const {
  std::vector<float> v;
  v.reserve(picked.size());
  for (std::int64_t r : picked)
    v.push_back(regime[static_cast<std::size_t>(r)] == positive ? 1.0f : 0.0f);
  return nn::Tensor(nn::Shape{static_cast<std::int64_t>(picked.size())}, v);
}

nn::Tensor TrainingData::training_anchor_codes() const {
  std::vector<std::int64_t> picked;
  for (std::int64_t r = 0; r < rows; ++r)
    if (!held_out_anchor(r))
      picked.push_back(r);
  return codes_of(picked);
}

namespace {

// The LDR's logit of every row of `data`, standardised over the training anchors' rows (a
// constant logit stays 0 after its mean is taken).
std::vector<float> standardised_logits(Ldr& ldr, const TrainingData& data) {
  nn::GradModeGuard no_grad(false);
  std::vector<float> logits(static_cast<std::size_t>(data.rows));
  for (std::int64_t b = 0; b < data.rows; b += 512) {
    std::vector<std::int64_t> part;
    for (std::int64_t r = b; r < std::min(data.rows, b + 512); ++r)
      part.push_back(r);
    const nn::Tensor l = ldr(data.codes_of(part));
    std::copy_n(l.data(), l.numel(), logits.data() + b);
  }
  double sum = 0, sum_sq = 0;
  std::int64_t n = 0;
  for (std::int64_t r = 0; r < data.rows; ++r)
    if (!data.held_out_anchor(r)) {
      const double v = logits[static_cast<std::size_t>(r)];
      sum += v;
      sum_sq += v * v;
      ++n;
    }
  const double mean = n > 0 ? sum / static_cast<double>(n) : 0.0;
  const double var = n > 0 ? std::max(0.0, sum_sq / static_cast<double>(n) - mean * mean) : 0.0;
  const double scale = var > 0 ? 1.0 / std::sqrt(var) : 1.0;
  for (float& v : logits)
    v = static_cast<float>((v - mean) * scale);
  return logits;
}

}  // namespace

ScoreTable ScoreTable::compute(const ExperimentConfig& config, const TrainingData& data,
                               const fs::path& run_dir, const CodeStandardization* ae2_map) {
  ScoreTable t;
  t.code_shape = data.code_shape;
  const std::int64_t per = data.code_shape[0] * data.code_shape[1] * data.code_shape[2];
  for (const JointRegimes& joint : data.joints) {
    Ldr ldr(config.ldr);
    nn::load_module(ldr, ldr_file(run_dir, joint.name));
    std::vector<std::int64_t> rows;
    if (config.ae2_training.score_samples == "all")
      for (std::int64_t r = 0; r < data.rows; ++r)
        rows.push_back(r);
    else
      rows = joint.rows;
    std::vector<float> values(static_cast<std::size_t>(per) * rows.size());
    for (std::size_t b = 0; b < rows.size(); b += 512) {
      const std::vector<std::int64_t> part(
          rows.begin() + static_cast<std::ptrdiff_t>(b),
          rows.begin() + static_cast<std::ptrdiff_t>(std::min(rows.size(), b + 512)));
      nn::Tensor y = data.codes_of(part);
      y.set_requires_grad(true);
      nn::Tensor v = nn::grad({nn::sum(ldr(y))}, {y})[0];
      if (ae2_map)
        v = ae2_map->to_mapped_gradient(v);
      if (config.ae2_training.score_normalization == "unit")
        v = unit_length_rows(v);
      std::copy_n(v.data(), v.numel(), values.data() + b * static_cast<std::size_t>(per));
    }
    if (config.ae2_training.score_normalization == "mean_unit") {
      // one divisor for all of the joint's rows, so it comes after every batch
      std::vector<std::int64_t> shape = {static_cast<std::int64_t>(rows.size())};
      shape.insert(shape.end(), data.code_shape.begin(), data.code_shape.end());
      values = mean_unit_length_rows(nn::Tensor(nn::Shape(shape), values)).to_vector();
    }
    t.rows.push_back(std::move(rows));
    t.values.push_back(std::move(values));
    if (config.ae2_training.logit_loss.weight > 0)
      t.logits.push_back(standardised_logits(ldr, data));
  }
  return t;
}

nn::Tensor ScoreTable::logits_of(std::size_t joint, const std::vector<std::int64_t>& at) const {
  std::vector<float> out;
  out.reserve(at.size());
  for (std::int64_t r : at)
    out.push_back(logits.at(joint)[static_cast<std::size_t>(r)]);
  return nn::Tensor(nn::Shape{static_cast<std::int64_t>(at.size())}, std::move(out));
}

std::vector<std::int64_t> ScoreTable::dataset_rows(std::size_t joint,
                                                   const std::vector<std::int64_t>& picked) const {
  std::vector<std::int64_t> out;
  out.reserve(picked.size());
  for (std::int64_t j : picked)
    out.push_back(rows[joint][static_cast<std::size_t>(j)]);
  return out;
}

nn::Tensor ScoreTable::scores_of(std::size_t joint, const std::vector<std::int64_t>& picked) const {
  return gather_rows(values[joint], code_shape, picked);
}

}  // namespace ropes::crl::detail
