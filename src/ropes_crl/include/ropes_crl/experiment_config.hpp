#pragma once
/// @file experiment_config.hpp
/// An experiment: which dataset it expects, the three networks and how each stage trains.
/// Read from a JSON file (the installed ones: share/ropes_crl/configs/*.json, one per paper
/// setting x preset); every field is required but ldr.input_normalization,
/// ae2.input_normalization and ae2.sparsity_diagonal (absent: the paper's choice), an unknown
/// key is an error, and the error names the file, the field, the value and what was expected.
#include "ropes_crl/networks.hpp"
#include "ropes_crl/score_sparsity.hpp"

#include <ropes_core/file_format_error.hpp>
#include <ropes_nn/lr_schedule.hpp>

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace ropes::crl {

/// How one stage's optimiser runs: Adam at `lr`, a schedule, steps, batch, micro-batches.
struct OptimizerConfig {
  double lr = 1e-3;
  std::string schedule = "constant";  ///< "constant" or "cosine" (to final_lr, after warmup)
  double final_lr = 0.0;
  std::int64_t warmup = 0;
  double clip_norm = 0.0;  ///< 0: no clipping
  /// The ropes_nn schedule over `steps` updates.
  nn::LrSchedule make_schedule(std::int64_t steps) const;
};

/// An extension of AE1's training, not the paper's method (which trains on clean images and
/// occludes only at test time): each training image, with probability `probability`, gets a
/// white square (every pixel 1) of a side drawn uniformly from [min_size, max_size] px at a
/// uniform position inside the image, as the occlusion suites paint them at test time, and AE1
/// learns to reconstruct the clean image from it. The config's optional
/// ae1.occlusion_augmentation {"probability", "min_size", "max_size"}; off when absent.
struct OcclusionAugmentation {
  double probability = 0;  ///< 0: off
  std::int64_t min_size = 0, max_size = 0;
};

/// A variant of AE1's objective, not the paper's (a plain MSE): each step draws half its
/// images' samples as before and, for each, the observational sample of the same anchor (the
/// other half; the step's image count is unchanged), and adds `weight` times the mean over
/// the step's (sample, camera) pairs of
///   || (x^_r - x^_o) - (x_r - x_o) ||^2 / max(|| x_r - x_o ||^2, 1)
/// (x the image in [0, 1], x^ AE1's reconstruction, r the sample, o its anchor's
/// observational sample; a pair whose sample is observational counts 0): the error of the
/// change an intervention makes, relative to that change, so that every intervention counts
/// alike however few pixels it moves. It uses the regimes (which samples share an anchor),
/// as the LDRs do, and no labels. The config's optional ae1.difference_loss {"weight"}; off
/// when absent. With the occlusion augmentation a pair is occluded together: when the
/// sample's image gets a square its partner gets one too (its own side and place, from a
/// stream of its own), the targets stay clean, and that pair counts in the reconstruction
/// term only, since a change that a square may hide cannot be asked of AE1 and its error,
/// relative to a small change, would be the squares' inpainting error.
struct DifferenceLoss {
  double weight = 0;  ///< 0: off
};

/// An extension of AE1's training, not the paper's method: AE1's encoder also learns to
/// order each joint's two interventions. Per intervened joint k a head h_k reads the code Y
/// (`head` "ldr": the LDR's architecture, config.ldr's widths and hidden, no input map;
/// "linear": one dense layer from the flattened code to a number); each step
/// draws `pairs_per_joint` anchors a joint among the training anchors (those the LDRs do
/// not hold out) and, for anchor a, the rows r1 of intervention 1 and r2 of intervention 2
/// of joint k at a, which share every other joint's angle. It adds `weight` times the mean
/// over the step's pairs of
///   softplus(-(h_k(E1(x_r2)) - h_k(E1(x_r1))))
/// (binary cross-entropy of the logit h_k(y2) - h_k(y1) with label 1), its gradient flowing
/// into the encoder. For an unordered pair, one sample from each intervention and every other
/// joint shared, P(the second is from intervention 2) = sigmoid(LDR_k(y2) - LDR_k(y1)), so
/// the term is the pair likelihood of a log-density-ratio model whose nuisance (the other
/// joints) cancels in the difference. It reads the regime and anchor columns, as the LDRs
/// do, and no angle. The pair images are clean (no occlusion squares) and are not
/// reconstructed; the heads are trained with AE1 and not saved with it. The config's optional
/// ae1.pair_heads {"weight", "pairs_per_joint", "head" (optional, "ldr" when absent)}; off
/// when absent.
struct PairHeads {
  double weight = 0;                 ///< 0: off
  std::int64_t pairs_per_joint = 1;  ///< anchors a joint, a step
  std::string head = "ldr";          ///< "ldr" or "linear"
};

/// Stage 1: AE1 on every camera image of the dataset, MSE.
struct Ae1Training {
  std::int64_t batch_size = 32;  ///< images a step (a sample of C cameras is C images)
  std::int64_t steps = 0;        ///< from "steps", or "epochs" x images / batch_size
  std::int64_t micro_batch = 32;
  OptimizerConfig optimizer;
  OcclusionAugmentation occlusion_augmentation;
  DifferenceLoss difference_loss;
  PairHeads pair_heads;
};

/// An extension of the LDRs' training, not the paper's method: besides the binary
/// cross-entropy of each sample, each batch adds `weight` times the mean over its samples'
/// pairs of softplus(-(LDR(y2) - LDR(y1))), y1 and y2 the codes of the samples of
/// intervention 1 and 2 of the joint at one anchor (the batch's sample and its partner, which
/// share every other joint's angle). For such a pair P(y2 is the one from intervention 2) =
/// sigmoid(LDR(y2) - LDR(y1)), so the term is the pair likelihood of the same log density
/// ratio, with the other joints cancelled; the unpaired term pins what the difference cannot
/// see (a function of the other joints alone). Early stopping still reads the unpaired
/// held-out loss. Regimes and anchors only, no angle. The config's optional
/// ldr.pair_loss {"weight"}; off when absent.
struct LdrPairLoss {
  double weight = 0;  ///< 0: off
};

/// An extension of the LDRs' training, not the paper's method: an exponential moving average
/// of each LDR's weights over its training steps, e <- d_t e + (1 - d_t) w after each step with
/// d_t = min(decay, (1 + t) / (10 + t)) at step t = 0, 1, ... (the average forgets its start
/// quickly). The held-out loss, early stopping and the saved classifier read the averaged
/// weights; the steps go on from the trained ones. A classifier's accuracy needs only the
/// logit's sign, but AE2 and the MCC read its value, which a constant-rate optimiser leaves
/// noisy from step to step; the average keeps what the steps agree on, at almost no cost (an
/// ensemble, ldr.members, averages independent runs instead). Regimes only, no angle. The
/// config's optional ldr.weight_average {"decay"}, decay in (0, 1); off when absent.
struct LdrWeightAverage {
  double decay = 0;  ///< 0: off
};

/// An extension of the LDRs' training, not the paper's method: one classifier over every
/// regime instead of one a joint. A network of the LDR's architecture with one output a
/// regime (each joint's two interventions, and with `observational` the observational
/// samples) learns the regime of each training sample by softmax cross-entropy. With the
/// regimes equally frequent its outputs estimate log p_r(y) up to one function of y, so
/// LDR_k = f_{k,2} - f_{k,1} estimates log p_{k,2}(y)/p_{k,1}(y), the quantity the paper's
/// per-joint classifier estimates, and its input gradient the same score difference. The
/// trunk learns from every sample, where a per-joint classifier sees 2 of a setting's 13
/// regimes: a joint whose interventions move few pixels (2C joint 5) borrows the features the
/// others teach. Each joint's LDR is saved as a plain classifier (the shared trunk, and the
/// difference of its two columns of the output layer), so nothing downstream changes. Each
/// joint's LDR is kept at the epoch of its own lowest held-out loss (its two interventions'
/// binary cross-entropy, as a per-joint classifier's early stopping); the stage stops when no
/// joint's has fallen for `patience` epochs. With ldr.pair_loss each joint's pairs add their
/// term on LDR_k; ldr.weight_average averages the one network. Regimes and anchors only, no
/// angle. The config's optional
/// ldr.all_regimes {"observational": bool (default true)}; off when absent. Not with
/// ldr.members > 1.
struct LdrAllRegimes {
  bool on = false;
  bool observational = true;  ///< the observational samples are a class too
};

/// Stage 2: one LDR per intervened joint, intervention 1 (label 0) against 2 (label 1),
/// early stopping on the held-out anchors.
struct LdrTraining {
  std::int64_t batch_size = 64;
  std::int64_t max_epochs = 30;
  std::int64_t patience = 5;       ///< epochs without a better held-out loss before stopping
  double held_out_fraction = 0.2;  ///< of the anchors, drawn by seed
  OptimizerConfig optimizer;
  LdrPairLoss pair_loss;
  LdrWeightAverage weight_average;
  LdrAllRegimes all_regimes;
};

/// Stage 3: AE2, reconstruction + lambda * sparsity.
/// An extension of AE2's objective, not the paper's method: each sparsity term k also asks
/// the latent t_k that estimates joint k to follow LDR_k's logit, adding `weight` times
/// 1 - corr(z_{t_k}, LDR_k(y)), the batch correlation over the reconstruction samples. The
/// sparsity term sees only the LDR's gradient at joint k's samples, scaled to unit length; the
/// logit itself (log p_2/p_1 of the joint's two interventions) is a function of joint k's
/// angle alone when the joints are independent. LDR_k is stage 2's frozen classifier, trained
/// on regimes only: no angle reaches the term. The config's optional ae2.logit_loss
/// {"weight"}; off when absent.
struct Ae2LogitLoss {
  double weight = 0;  ///< 0: off
};

struct Ae2Training {
  std::string mode = "per_joint";  ///< "per_joint" (one AE2 a joint) or "joint" (one for all)
  double lambda = 1.0;
  SparsityNorm norm = SparsityNorm::kL2Squared;
  SparsityDiagonal diagonal = SparsityDiagonal::kMeanAbs;  ///< "sparsity_diagonal", optional
  /// "none", "unit" (|v| = 1 per sample) or "mean_unit" (each joint's v divided by one
  /// number, their mean length: the mean |v| is 1 and the samples keep their relative sizes)
  std::string score_normalization = "none";
  std::string score_samples = "intervened";  ///< "intervened" (joint i's samples) or "all"
  std::int64_t batch_size = 64;              ///< reconstruction samples a step (all regimes)
  std::int64_t sparsity_batch_size = 64;     ///< per joint, a step
  std::int64_t steps = 4000;
  std::int64_t micro_batch = 128;  ///< rows of one micro-batch (reconstruction + sparsity)
  OptimizerConfig optimizer;
  bool lambda0_baseline = true;  ///< also train the lambda = 0 autoencoder (a baseline)
  Ae2LogitLoss logit_loss;       ///< an extension, off by default (the lambda = 0 AE2 never)
};

struct ExperimentConfig {
  std::string name;                     ///< e.g. "1c-small"
  std::string preset;                   ///< "tiny", "small" or "paper"
  std::string source;                   ///< where its numbers come from
  std::vector<std::string> deviations;  ///< each way it departs from the paper's appendix

  // the dataset it expects
  std::string dataset_config;  ///< the ropes-generate config that makes it (e.g. "small-1c")
  std::int64_t cameras = 1;
  std::int64_t image_size = 128;
  std::vector<std::string> joints;  ///< intervened joints, in latent order

  Ae1Spec ae1;
  Ae1Training ae1_training;
  LdrSpec ldr;
  LdrTraining ldr_training;
  Ae2Spec ae2;
  Ae2Training ae2_training;

  std::int64_t log_every = 50;
  std::int64_t checkpoint_every = 200;

  /// The code Y a sample gives: [cameras * ae1.code_channels, 8, 8].
  std::int64_t code_channels() const { return cameras * ae1.code_channels; }
  /// Everything above as JSON (what run.json and the weight files record).
  nlohmann::json to_json() const;
  /// Parses and validates; `where` names the source in errors. Throws core::ConfigError
  /// naming `where`, the field, the value and what was expected.
  static ExperimentConfig from_json(const nlohmann::json& j, const std::string& where);
  /// With Ae1Training::steps computed from "epochs" when the config gives epochs.
  void resolve_epochs(std::int64_t dataset_images);

  nlohmann::json raw;  ///< the file as read (with "epochs" if given)
};

/// The installed experiment configs' directory, share/ropes_crl/configs, found as
/// core::find_package_share finds it (beside the executable, a sourced install space, or
/// where it was installed), so a moved install space finds its own. Throws
/// std::runtime_error naming the places looked when none holds it.
std::filesystem::path installed_config_dir();

/// Reads `name_or_path`: a file path, or the name of an installed config ("1c-small").
/// Throws core::ConfigError naming the file and the field for anything invalid, and
/// listing the installed names when a name is not found; core::FileFormatError for a file
/// that is not JSON or too large.
ExperimentConfig load_experiment_config(const std::string& name_or_path);

}  // namespace ropes::crl
