#pragma once
/// @file screening.hpp
/// screen_run: how much of each joint an AE1's code holds, measured before any AE2 trains.
///
/// No AE2 can recover what AE1's code Y does not hold, so an AE1 is screened by two
/// measures that need only stages 1 and 2 of a run (`ropes-train --stages ae1,ldr`):
///   - per joint, the explained variance R^2 = 1 - MSE / Var of a supervised probe from Y to
///     the joint angle (a ridge regression and a small MLP, run_evaluation.hpp's probes),
///     fitted on the codes and labels of most of the training set's anchors and scored on
///     the rest. These labels serve this diagnostic only; the run never sees them;
///   - per joint, the LDR classifier's held-out accuracy against the Bayes accuracy of its
///     two interventions (run.json, written by the trainer).
/// A probe R^2 well below 1 or an LDR far from Bayes bounds what ROPES can reach on that
/// joint, whatever AE2 does.
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>
#include <vector>

namespace ropes::eval {

struct ScreeningOptions {
  std::int64_t probe_steps = 3000;  ///< MLP probe training steps (0: the linear probe only)
  std::uint64_t seed = 0;           ///< which anchors are held out, the MLP's draws
  double test_fraction = 0.2;       ///< of the training set's anchors the probes score on
};

struct Screening {
  std::string run_dir, config_name, dataset_id;
  std::vector<std::string> joints;
  std::int64_t train_rows = 0, test_rows = 0;        ///< every regime of their anchors
  std::int64_t train_anchors = 0, test_anchors = 0;  ///< disjoint
  std::uint64_t seed = 0;
  std::int64_t probe_steps = 0;
  /// per joint, on the test rows: the angle's variance (rad^2), each probe's MSE and R^2
  /// (1 - MSE / variance); the MLP's are empty when probe_steps is 0
  std::vector<double> angle_variance, probe_linear_mse, probe_linear_r2, probe_mlp_mse,
      probe_mlp_r2;
  /// per joint, from run.json: the LDR's held-out accuracy and the Bayes accuracy of its
  /// interventions (NaN for a joint whose LDR has not trained yet)
  std::vector<double> ldr_accuracy, bayes_accuracy;

  /// {"format": "ropes-eval-screen", "format_version": 1, "run", "config", "dataset",
  /// "seed", "probe_steps", "split": {...}, "joints", "angle_variance", "probe_linear_mse",
  /// "probe_linear_r2", "probe_mlp_mse", "probe_mlp_r2", "ldr_accuracy", "bayes_accuracy"}
  /// (NaN as null).
  nlohmann::json to_json() const;
  /// One line per joint: the probes' R^2 and MSE, the angle variance, LDR accuracy / Bayes.
  std::string table() const;
  /// The same as a Markdown table with a line on what it measures.
  std::string markdown() const;
};

/// Screens the run in `run_dir`: needs its run.json, RUN/codes.npy (stage 1) and the training
/// set run.json names (its angles and anchors); the LDR columns come from run.json when stage 2
/// ran. The test anchors are the first round(test_fraction * anchors) (at least 1) of
/// nn::shuffled_indices(anchors, seed, 0); every row of an anchor goes to the same side.
/// Throws std::invalid_argument for options out of range (test_fraction outside (0, 1),
/// probe_steps < 0) or a training set of fewer than 2 anchors; nn::FileFormatError naming the
/// file for a run without codes.npy (stage 1 not done), an unreadable run.json, codes that do
/// not match the training set, or a training set that lacks a joint of the run. Cost: reads the
/// codes and the training set's labels, trains the MLP probe (seconds at 3000 steps).
Screening screen_run(const std::filesystem::path& run_dir, const ScreeningOptions& options = {});

}  // namespace ropes::eval
