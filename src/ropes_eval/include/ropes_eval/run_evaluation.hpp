#pragma once
/// @file run_evaluation.hpp
/// The first evaluation of a trained run (what `ropes-eval --run RUN --data DIR` prints):
/// on the observational samples of a dataset the run did not train on, per joint
///   - MCC: |Pearson| of latent k and joint k on the test half (the paper's measure),
///   - MSE (rad^2) of the affine calibration of joint k from latent k, fitted on the
///     calibration half and measured on the test half,
///   - beside them |Spearman|, the best-assignment MCC (joints matched to distinct latents)
///     and the MSE of the affine calibration from every latent of the method,
/// beside the baselines (the lambda = 0 AE2's latent k; LDR_k(y), the classifier's logit)
/// and the diagnostics (supervised probes from Y to each joint — a linear one and a small MLP,
/// fitted on the calibration half — and the LDR's held-out accuracy against Bayes). Labels
/// (the angles) are read here only.
#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace ropes::eval {

struct RunEvaluationOptions {
  double calibration_fraction = 0.5;  ///< of the observational samples, drawn by seed
  std::uint64_t seed = 0;
  std::int64_t probe_steps = 3000;  ///< MLP probe training steps (0: no MLP probe)
  /// paper_results.json (the paper's table); empty: the installed one.
  std::filesystem::path paper_results;
};

/// One method's numbers per joint (NaN where a latent is constant on the test samples).
struct MethodScores {
  std::string method;
  std::vector<double> mcc;       ///< |Pearson| of latent k and joint k (the paper's MCC)
  std::vector<double> mse;       ///< rad^2, the affine fit of joint k from latent k
  std::vector<double> spearman;  ///< |Spearman| of latent k and joint k
  /// |Pearson| of joint k and latent best_assignment[k], the maximum-weight matching of
  /// joints to distinct latents (the best-assignment MCC of the CRL literature)
  std::vector<double> best_assignment_mcc;
  std::vector<std::int64_t> best_assignment;
  std::vector<double> mse_all_latents;  ///< rad^2, the affine fit of joint k from every latent
};

struct RunEvaluation {
  std::string run_dir, data_dir, config_name, setting, dataset_id, train_dataset_id;
  std::vector<std::string> joints;
  std::int64_t calibration_samples = 0, test_samples = 0;
  std::vector<MethodScores> methods;  ///< "ropes" first, then the baselines
  std::vector<double> probe_linear_mse, probe_mlp_mse, angle_variance;
  std::vector<double> ldr_accuracy, bayes_accuracy;
  std::vector<double> paper_mcc, paper_mse;  ///< NaN where the paper gives none
  nlohmann::json calibration;                ///< ropes' affine fit (an Estimator Calibration)
  nlohmann::json to_json() const;
  /// The per-joint table, plain text, ROPES beside the paper and the baselines.
  std::string table() const;
};

/// Evaluates the run in `run_dir` on the dataset in `data_dir`. Throws std::invalid_argument
/// when `data_dir` is the dataset the run trained on (same dataset id), when it lacks a
/// joint of the run or observational samples, or when its images differ from the run's
/// (cameras, size); nn::FileFormatError for unreadable files.
RunEvaluation evaluate_run(const std::filesystem::path& run_dir,
                           const std::filesystem::path& data_dir,
                           const RunEvaluationOptions& options = {});

/// The installed paper_results.json.
std::filesystem::path installed_paper_results();

namespace detail {
/// The linear probe of the diagnostics: ridge regression (lambda 1e-3) of each column of
/// `angles` on [Y, 1] fitted on rows `cal`, Y standardised with the calibration rows'
/// statistics; a column of Y whose sd there is <= 1e-3 of the largest column's is left out
/// (its calibration values carry nothing, and dividing by their tiny spread would blow up
/// the test rows). Returns the test rows' MSE per angle column.
std::vector<double> linear_probe(const Eigen::MatrixXd& y, const Eigen::MatrixXd& angles,
                                 const std::vector<Eigen::Index>& cal,
                                 const std::vector<Eigen::Index>& test);
}  // namespace detail

}  // namespace ropes::eval
