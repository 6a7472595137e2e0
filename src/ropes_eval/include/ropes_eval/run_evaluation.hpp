#pragma once
/// @file run_evaluation.hpp
/// The evaluation of a trained run (what `ropes-eval --run RUN --data DIR` prints), by the
/// paper's protocol: on the observational samples of a dataset the run did not train on,
/// `repeats` times (15) a seeded draw of `calibration_samples` (1,000) labelled samples and a
/// disjoint set of `test_samples` (500); per joint, the mean and standard deviation over the
/// repeats of
///   - MCC: |Pearson| of latent k and joint k on the test samples (the paper's measure),
///   - MSE (rad^2) of the affine calibration of joint k from latent k, fitted on the
///     calibration samples and measured on the test samples,
///   - beside them |Spearman|, the best-assignment MCC (joints matched to distinct latents)
///     and the MSE of the affine calibration from every latent of the method,
/// for ROPES and the baselines (the lambda = 0 AE2's latent k; LDR_k(y), the classifier's
/// logit; principal component k of AE1's code, the PCA fitted on the run's training codes
/// RUN/codes.npy), and the diagnostics of repeat 0 (supervised probes from Y to each joint — a
/// linear one and a small MLP, fitted on its calibration samples — and the LDR's held-out accuracy
/// against Bayes). Labels (the angles) are read here only.
#include <ropes_crl/calibration.hpp>

#include <Eigen/Core>
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <limits>
#include <memory>
#include <optional>
#include <string>
#include <vector>

namespace ropes::eval {

class SupervisedEncoder;

/// What the occluded evaluations of one run on one test set share, computed by the first that
/// needs it and reused by the others (RunEvaluationOptions::cache): AE1's codes of the clean
/// observational images (for RunEvaluation::code_shift) and the robot's silhouettes (for
/// OcclusionSplit), neither of which depends on the squares. Filled by evaluate_run only.
struct EvaluationCache {
  std::filesystem::path run_dir, data_dir;  ///< what it holds (empty: nothing yet)
  Eigen::MatrixXd clean_codes;              ///< [observational samples, code]; empty: not yet
  /// per observational sample, its robot pixels in every camera and its silhouette
  /// ([cameras, side, side], true on the robot); empty: not yet
  std::vector<std::int64_t> robot_pixels;
  std::vector<std::vector<bool>> silhouettes;
};

struct RunEvaluationOptions {
  std::int64_t repeats = 15;                ///< draws of a calibration set and a test set
  std::int64_t calibration_samples = 1000;  ///< labelled samples each repeat fits on
  std::int64_t test_samples = 500;          ///< disjoint from them, each repeat scores on
  std::uint64_t seed = 0;                   ///< the draws' and the MLP probe's
  std::int64_t probe_steps = 3000;          ///< MLP probe training steps (0: no MLP probe)
  /// The occlusion suite: a white square of this many pixels painted into every camera image
  /// of every sample before it is encoded (occlusion.hpp); 0: none.
  std::int64_t occlusion = 0;
  std::uint64_t occlusion_seed = 0;  ///< where the squares go (occlusion_square)
  /// With an occlusion, the cameras whose images get the square; empty (the paper's test):
  /// every camera. One camera of two is a diagnostic: does the clean view carry the pose?
  std::vector<std::int64_t> occluded_cameras;
  /// With an occlusion, optional: each camera's robot silhouette for one dataset row, from
  /// its angles (every column of the dataset's `angles`, in its metadata.joint_names order),
  /// into `masks` ([cameras, side, side] bytes, nonzero on the robot). When given, the test
  /// samples are split by whether a square hides robot pixels (RunEvaluation::occlusion_split).
  /// ropes-eval's suites render it with the test set's own rig.
  std::function<void(const std::vector<double>& angles, std::uint8_t* masks)> robot_masks;
  /// Optional: the clean codes and silhouettes kept between the occluded evaluations of one
  /// run on one test set (ropes-eval's suites share one per test set); a cache that holds
  /// another run or test set is refused. Null: each evaluation computes its own.
  std::shared_ptr<EvaluationCache> cache;
  /// Supervised baselines (supervised.hpp), scored as methods named "supervised_<p>%" (p:
  /// the percentage of labelled training samples); their latents are their angle estimates,
  /// and their "mse" is the estimate's own error (no calibration). Not owned.
  std::vector<const SupervisedEncoder*> supervised;
  /// paper_results.json (the paper's table); empty: the installed one.
  std::filesystem::path paper_results;
};

/// The range of one of the protocol's counts (check_protocol; the tools' flags say the same).
struct ProtocolRange {
  std::int64_t low, high;
  bool holds(std::int64_t v) const { return v >= low && v <= high; }
  std::string text() const { return std::to_string(low) + ".." + std::to_string(high); }
};
inline constexpr ProtocolRange kRepeatsRange{1, 10000};
/// calibration_samples and test_samples: at least 2, at most 10^9 (their sum stays far from
/// overflow, and no dataset holds more rows)
inline constexpr ProtocolRange kSamplesRange{2, 1000000000};
inline constexpr ProtocolRange kProbeStepsRange{0, 1000000000};

/// The protocol's counts: repeats, calibration_samples, test_samples and probe_steps each in
/// its range above. Throws std::invalid_argument naming the field, its value and the range.
/// evaluate_run, run_suites and run_main_job check with it before anything is read.
void check_protocol(const RunEvaluationOptions& options);

/// One method's numbers per joint for one repeat (NaN where a latent is constant on the
/// test samples).
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

/// One method over the repeats: each repeat's scores, their mean and standard deviation
/// (with n - 1) per joint.
struct MethodSummary {
  std::string method;
  std::vector<MethodScores> repeats;
  MethodScores mean, std;
};

/// The occlusion diagnostic of robot_masks: each test sample is in one of two groups, its
/// squares hiding at least one robot pixel (in any occluded camera) or none; per method
/// (RunEvaluation::methods' order) and joint, |Pearson| of latent k and joint k on each
/// group's test samples, the mean over the repeats (a repeat whose group has fewer than 3
/// samples or a constant latent there is left out; NaN when every repeat is).
struct OcclusionSplit {
  double share_hiding = 0;  ///< of the observational samples, those whose squares hide the robot
  double robot_hidden = 0;  ///< mean share of a sample's robot pixels the squares hide
  std::vector<std::string> methods;
  std::vector<std::vector<double>> mcc_hiding, mcc_missing;  ///< [method][joint]
};

struct RunEvaluation {
  std::string run_dir, data_dir, config_name, setting, dataset_id, train_dataset_id;
  std::vector<std::string> joints;
  /// what the run's training adds to the paper's method (an extension, never the
  /// reproduction), e.g. AE1's occlusion augmentation; empty: none
  std::vector<std::string> extensions;
  std::int64_t calibration_samples = 0, test_samples = 0, observational_samples = 0;
  std::uint64_t seed = 0;
  std::int64_t occlusion = 0;  ///< the square's side in pixels (0: none)
  std::uint64_t occlusion_seed = 0;
  std::vector<std::int64_t> occluded_cameras;  ///< with an occlusion; empty: every camera
  /// With an occlusion: how far the squares move AE1's code, E|Y_occluded - Y_clean|^2 /
  /// E|Y_clean - mean(Y_clean)|^2 over the observational samples (0: the code does not move;
  /// 1: it moves as far as a clean code lies from the mean code). NaN without an occlusion.
  double code_shift = std::numeric_limits<double>::quiet_NaN();
  std::optional<OcclusionSplit> occlusion_split;  ///< with an occlusion and robot_masks
  std::vector<MethodSummary> methods;             ///< "ropes" first, then the baselines
  std::int64_t best_repeat = 0;  ///< the repeat of ROPES' highest mean MCC (for plots)
  /// ROPES on the best repeat's test samples, for the scatter plots: per joint k, latent k,
  /// joint k estimated by that repeat's affine calibration, and the true angle (radians)
  std::vector<std::vector<double>> scatter_latent, scatter_estimate, scatter_truth;
  std::vector<double> probe_linear_mse, probe_mlp_mse, angle_variance;
  std::vector<double> ldr_accuracy, bayes_accuracy;
  std::vector<double> paper_mcc, paper_mse;  ///< NaN where the paper gives none
  /// ROPES' affine fit of repeat 0, for the Estimator; records the run it was fitted for
  crl::Calibration calibration;
  /// {"training": run.json's provenance (null for a run that recorded none), "evaluation":
  /// this process's} (ropes_nn/build_info.hpp)
  nlohmann::json provenance;
  /// What differs between the two builds in what decides the bits ("isa_level: a vs b");
  /// empty when the run was trained by a build that gives this one's bytes. The table and
  /// results.md then say that the numbers compare to rounding, not bit for bit.
  std::vector<std::string> provenance_differences;
  nlohmann::json to_json() const;
  /// The per-joint table, plain text, ROPES beside the paper and the baselines.
  std::string table() const;
  /// results.md: the run laid out like the paper's Table 1 (a joint's MCC and MSE side by
  /// side, the paper's row below, then the difference, marked "worse" or "better"), the
  /// baselines' MCC, and the diagnostics. Markdown, one document.
  std::string markdown() const;
};

/// Evaluates the run in `run_dir` on the dataset in `data_dir`. Throws std::invalid_argument
/// when `data_dir` is the dataset the run trained on (same dataset id), when it lacks a
/// joint of the run, when it holds fewer observational samples than calibration_samples +
/// test_samples, when an option is out of range (check_protocol's counts, occluded_cameras
/// without an occlusion), when options.cache holds another run or test set, or when its images
/// differ from the run's (cameras, size); core::FileFormatError for unreadable files.
RunEvaluation evaluate_run(const std::filesystem::path& run_dir,
                           const std::filesystem::path& data_dir,
                           const RunEvaluationOptions& options = {});

/// The files of an evaluation written as ropes-eval --data writes them: `results`
/// (results.json), the markdown beside it (the same name with .md; `results` + ".md" when
/// it already ends in .md) and calibration.json in the same directory.
struct EvaluationFiles {
  std::filesystem::path results, markdown, calibration;
};
/// The three paths for `results`. Throws std::invalid_argument, naming it, when `results`
/// is itself named calibration.json (the calibration would overwrite it).
EvaluationFiles evaluation_files(const std::filesystem::path& results);
/// Writes `ev` into evaluation_files(results): to_json() with indent 2, markdown() and the
/// calibration, each atomically, after creating the directory. Throws as evaluation_files,
/// core::FileFormatError naming a file that cannot be written.
EvaluationFiles write_evaluation(const RunEvaluation& ev, const std::filesystem::path& results);

/// The installed paper_results.json.
std::filesystem::path installed_paper_results();

/// The samples one repeat of the protocol uses: indices into the observational samples.
struct ProtocolSplit {
  std::vector<Eigen::Index> calibration, test;
};

/// The protocol's draws: for repeat r, the permutation core::shuffled_indices(n, seed, r) of
/// [0, n), its first `calibration` entries and the `test` entries after them — disjoint by
/// construction, and checked. Throws std::invalid_argument when repeats < 1, calibration < 2,
/// test < 2 or calibration + test > n (naming the numbers).
std::vector<ProtocolSplit> protocol_splits(std::int64_t n, std::int64_t repeats,
                                           std::int64_t calibration, std::int64_t test,
                                           std::uint64_t seed);

}  // namespace ropes::eval
