#pragma once
/// @file run_directory.hpp
/// A run directory of ropes-train, read: the one place that knows run.json's keys. ropes_eval,
/// ropes-stream and ropes-run read a run through it; ropes_crl's trainer writes it.
///
///   RUN/run.json        format "ropes-run": the config, the dataset (its id and directory),
///                       the seed, the joints, the provenance, each stage's record, and
///                       "complete" once every stage has finished
///   RUN/metrics.jsonl   one JSON object a line: the training curves
///   RUN/codes.npy       stage 1's codes of every training row, f32 [rows, C, 8, 8]
///   RUN/*.safetensors   the networks' weights (Estimator::load reads them)
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <utility>
#include <vector>

#include "ropes_crl/experiment_config.hpp"

namespace ropes::crl {

/// What stage 2 recorded of one joint's LDR classifier.
struct LdrRecord {
  double held_out_loss = 0;      ///< the held-out loss at the epoch early stopping kept
  double held_out_accuracy = 0;  ///< its held-out accuracy there
  double bayes_accuracy = 0;     ///< the best accuracy any classifier reaches on the two regimes
  std::int64_t epochs = 0;       ///< epochs trained
};

/// One AE2's sparsity matrix: row k is E|J_gᵀ v_k| over joint k's samples, a column a latent.
struct SparsityMatrix {
  std::string model;  ///< the AE2's name: a joint's ("joint2"), "joint" or "lambda0"
  std::vector<std::vector<double>> rows;
};

class RunDirectory {
 public:
  /// Opens `dir` and reads RUN/run.json, at any stage of training. Throws
  /// core::FileFormatError naming run.json: missing ("is 'DIR' a run directory of
  /// ropes-train?"), unreadable, not JSON, not format "ropes-run", or a field missing or of
  /// another type (config, joints, data_dir, dataset, seed), with the field named; a config
  /// that is not one is a core::ConfigError (a FileFormatError) naming run.json and the field.
  static RunDirectory open(const std::filesystem::path& dir);

  const std::filesystem::path& dir() const { return dir_; }
  std::filesystem::path run_file() const { return dir_ / "run.json"; }
  std::filesystem::path metrics_file() const { return dir_ / "metrics.jsonl"; }
  std::filesystem::path codes_file() const { return dir_ / "codes.npy"; }

  /// The experiment config the run was trained with (run.json's copy, not the installed one).
  const ExperimentConfig& config() const { return config_; }
  /// The joints the run estimates, in latent order.
  const std::vector<std::string>& joints() const { return joints_; }
  /// The training set's directory, as the trainer saw it (absolute).
  const std::filesystem::path& data_dir() const { return data_dir_; }
  /// The training set's dataset id (its manifest's).
  const std::string& dataset_id() const { return dataset_id_; }
  std::uint64_t seed() const { return seed_; }
  /// True once every stage has finished (the weights of all networks are there).
  bool complete() const { return complete_; }
  /// The build that trained the run (ropes_nn's provenance), null for a run from before it
  /// was recorded.
  const nlohmann::json& provenance() const { return provenance_; }
  /// Stage 2's record of `joint`'s LDR; nullopt before stage 2 has trained it.
  std::optional<LdrRecord> ldr(const std::string& joint) const;
  /// Stage 3's sparsity matrices, one an AE2; empty before stage 3 has finished.
  const std::vector<SparsityMatrix>& sparsity_matrices() const { return sparsity_; }

 private:
  std::filesystem::path dir_, data_dir_;
  ExperimentConfig config_;
  std::vector<std::string> joints_;
  std::string dataset_id_;
  std::uint64_t seed_ = 0;
  bool complete_ = false;
  nlohmann::json provenance_, ldr_;
  std::vector<SparsityMatrix> sparsity_;
};

}  // namespace ropes::crl
