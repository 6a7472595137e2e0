#pragma once
// What the trainer reads of a dataset: the reader, checked against the config; the regimes
// of each intervened joint; the held-out anchors; the codes Y once AE1 has made them; and
// the score differences of the frozen LDRs.
#include "ropes_crl/experiment_config.hpp"

#include <ropes_core/dataset.hpp>
#include <ropes_nn/tensor.hpp>

#include <cstdint>
#include <filesystem>
#include <set>
#include <string>
#include <utility>
#include <vector>

namespace ropes::crl::detail {

struct JointRegimes {
  std::string name;
  std::int32_t regime1 = 0, regime2 = 0;  ///< intervention 1 (label 0) and 2 (label 1)
  std::vector<std::int64_t> rows;         ///< the rows of both, in dataset order
  double bayes_accuracy = 0;
};

struct TrainingData {
  std::filesystem::path dir;
  core::DatasetReader reader;
  std::string dataset_id;
  std::int64_t rows = 0;
  std::vector<std::int32_t> regime;
  std::vector<std::int64_t> anchor;
  /// per row, the row of its anchor's observational sample (itself for an observational
  /// row); -1 where the anchor has none in the dataset
  std::vector<std::int64_t> observational_row;
  std::vector<JointRegimes> joints;  ///< in config.joints order
  std::set<std::int64_t> held_out_anchors;
  std::vector<std::int64_t> code_shape;  ///< [C, 8, 8]
  std::vector<float> codes;              ///< [rows, C, 8, 8] once load_codes() ran

  /// Opens and checks the dataset against `config` (throws std::invalid_argument naming
  /// the manifest, the field, its value and the config's). Draws the held-out anchors.
  static TrainingData open(const ExperimentConfig& config, const std::filesystem::path& dir,
                           std::uint64_t seed);
  bool held_out_anchor(std::int64_t row) const {
    return held_out_anchors.count(anchor[static_cast<std::size_t>(row)]) != 0;
  }
  /// The pairs of `joint`'s two interventions at one training anchor (not held out), which
  /// share every other joint's angle: (row of intervention 1, row of intervention 2), in
  /// anchor order; an anchor without both has none.
  std::vector<std::pair<std::int64_t, std::int64_t>> training_pairs(
      const JointRegimes& joint) const;
  void load_codes(const std::filesystem::path& path);
  /// The codes of every row of the training anchors (not held out): what the input maps of
  /// the LDRs and AE2 are fitted on. [rows, C, 8, 8]
  nn::Tensor training_anchor_codes() const;
  nn::Tensor codes_of(const std::vector<std::int64_t>& rows) const;
  /// 1 where regime == positive, else 0: [rows.size()]
  nn::Tensor labels_of(const std::vector<std::int64_t>& rows, std::int32_t positive) const;
};

/// v_k(y) = grad_y LDR_k(y) on the rows the sparsity term of joint k averages over.
struct ScoreTable {
  std::vector<std::vector<std::int64_t>> rows;  ///< per joint: dataset rows
  std::vector<std::vector<float>> values;       ///< per joint: [rows, C, 8, 8]
  std::vector<std::int64_t> code_shape;
  /// per joint, with ae2.logit_loss only: LDR_k's logit of every dataset row, standardised
  /// over the training anchors' rows (mean 0, variance 1); empty otherwise
  std::vector<std::vector<float>> logits;

  /// `ae2_map`: AE2's input map when it standardises its codes (the scores are then moved
  /// to its coordinates before any unit normalisation), else null.
  static ScoreTable compute(const ExperimentConfig& config, const TrainingData& data,
                            const std::filesystem::path& run_dir,
                            const CodeStandardization* ae2_map);
  std::vector<std::int64_t> dataset_rows(std::size_t joint,
                                         const std::vector<std::int64_t>& picked) const;
  nn::Tensor scores_of(std::size_t joint, const std::vector<std::int64_t>& picked) const;
  /// the standardised logits of `joint` at the dataset rows `at`: [at.size()]
  nn::Tensor logits_of(std::size_t joint, const std::vector<std::int64_t>& at) const;
};

}  // namespace ropes::crl::detail
