#pragma once
/// @file trainer.hpp
/// The three stages of ROPES on a dataset directory, into a run directory, resumable.
///
/// Run directory (every file written under a temporary name and renamed):
///   run.json                    config, dataset id, seed, threads, versions, per-stage wall
///                               time, LDR accuracies against Bayes, the sparsity matrices
///   metrics.jsonl               one JSON object per logged step (stage, losses, rates, rows
///                               of the sparsity matrix, LDR accuracy)
///   ae1.safetensors             AE1 weights; metadata "ropes.network" = {"kind": "ae1",
///                               "spec": ...} and "ropes.config"
///   codes.npy                   Y = E1(x) of every dataset row, f32 [rows, C, 8, 8]
///   ldr.<joint>.safetensors     the early-stopped LDR of each intervened joint
///   ae2.<model>.safetensors     AE2 weights: per_joint mode one model per joint (<model> =
///                               the joint's name), joint mode one ("joint"), and the
///                               lambda = 0 baseline ("lambda0") when the config asks for it
///   *.checkpoint.safetensors    the state of a stage in progress (removed when it finishes)
/// A run killed at any point resumes when started again with the same arguments: finished
/// stages are kept, AE1 and AE2 continue from their last checkpoint (same seed and thread
/// count: the same bytes as a run never killed), an LDR restarts its joint (seconds).
///
/// Threads: AE1, the encoding, the LDRs and the score differences compute on all
/// `threads`. Stage 3 trains min(threads, M) of its M AE2s at once, each on
/// threads / min(threads, M) threads (an AE2 step is too small to share: at 2 threads it
/// takes as long as at 1); the split depends on the thread count and the config alone, so a
/// resumed stage computes exactly as an uninterrupted one. When one AE2 fails, the others
/// stop at their next step with a checkpoint of it.
#include "ropes_crl/experiment_config.hpp"

#include <ropes_nn/tensor.hpp>

#include <cstdint>
#include <filesystem>
#include <functional>
#include <string>
#include <vector>

namespace ropes::crl {

struct TrainOptions {
  std::uint64_t seed = 0;
  int threads = 1;
  /// The last stage to run: 1 AE1 (and the codes), 2 the LDRs, 3 AE2 (the whole run). A run
  /// stopped before stage 3 is not complete (run.json has no "complete"); the same call with
  /// a later stage continues it. Stages 1 and 2 are what screens an AE1 (ropes-eval
  /// --screen) without training an AE2.
  int last_stage = 3;
  /// true: a one-line progress bar on stderr (for a terminal); false: a log line every
  /// log_every steps.
  bool progress_bar = false;
  /// Test hook: called after each checkpoint is written with (stage, step); unset in normal
  /// use. In stage 3 it is called from the thread of each AE2, possibly at the same time.
  std::function<void(const std::string&, std::int64_t)> on_checkpoint;
  /// Called with every record written to metrics.jsonl, right after it is written (what
  /// ropes-train --status publishes). In stage 3 it is called from the thread of each AE2,
  /// one call at a time.
  std::function<void(const nlohmann::json&)> on_metrics;
};

/// Runs (or resumes) the stages of `config` up to options.last_stage on the dataset in
/// `data_dir` into `run_dir`.
/// Throws std::invalid_argument, before writing anything, when the dataset does not match
/// the config (cameras, image size, a joint without both interventions, missing columns) or
/// `run_dir` holds a run of another config, dataset, seed or thread count; std::runtime_error
/// naming the stage and step when a loss or gradient is not finite (the last checkpoint is
/// kept); FileFormatError for unreadable inputs.
void train(const ExperimentConfig& config, const std::filesystem::path& data_dir,
           const std::filesystem::path& run_dir, const TrainOptions& options);

/// The occlusion augmentation of AE1's training step `step` (OcclusionAugmentation, an
/// extension): a copy of `images` [n, 1, S, S] (values in [0, 1]) in which each image, with
/// probability a.probability, has a square of a side uniform on [a.min_size, a.max_size] at a
/// corner uniform on those that keep it inside set to 1 (white). Per image, in order, the
/// Philox stream (seed, step) draws whether, the side, the column, then the row, so a step's
/// squares are the same in a resumed run. When `squared` is given, it is set to 1 for each
/// image that got a square and 0 for the others. Throws std::invalid_argument for another
/// shape or sizes outside [1, S].
nn::Tensor occlusion_augmented(const nn::Tensor& images, const OcclusionAugmentation& a,
                               std::uint64_t seed, std::uint64_t step,
                               std::vector<char>* squared = nullptr);

/// The same squares' draw for the images `squared` names (1: a square, 0: none; one entry per
/// image), so that the partners of a pair are occluded together: per image with a square, in
/// order, the Philox stream (seed, step) draws the side, the column, then the row. Throws
/// std::invalid_argument as above, or when `squared` has another length.
nn::Tensor occlusion_augmented_where(const nn::Tensor& images, const std::vector<char>& squared,
                                     const OcclusionAugmentation& a, std::uint64_t seed,
                                     std::uint64_t step);

/// The per-pair loss of AE1's difference-loss variant (DifferenceLoss): for n images `x`
/// [n, 1, S, S] (in [0, 1]), their anchors' observational images `xo`, AE1's reconstructions
/// `recon` and `recon_o` of both and `mask` [n] (0 where an image is its own observational
/// one, else 1), the [n] values
///   (mean((recon - x)^2) + mean((recon_o - xo)^2)) / 2
///     + weight * mask * sum(((recon - recon_o) - (x - xo))^2) / max(sum((x - xo)^2), 1),
/// sums and means over an image's pixels; x, xo and mask are constants. Their mean over the
/// step's pairs is the step's loss. Throws std::invalid_argument when the shapes differ.
nn::Tensor ae1_difference_loss(const nn::Tensor& recon, const nn::Tensor& recon_o,
                               const nn::Tensor& x, const nn::Tensor& xo, const nn::Tensor& mask,
                               double weight);

/// The version of ropes_crl ("0.1.0").
const char* ropes_crl_version();

}  // namespace ropes::crl
