#pragma once
/// @file screening.hpp
/// screen_run: how much of each joint an AE1's code holds, measured before any AE2 trains.
///
/// No AE2 can recover what AE1's code Y does not hold, so an AE1 is screened by two
/// measures that need only stages 1 and 2 of a run (`ropes-train --stages ae1,ldr`):
///   - per joint, the explained variance R^2 = 1 - MSE / Var of a supervised probe from Y to
///     the joint angle (a ridge regression and a small MLP, run_evaluation.hpp's probes),
///     fitted on the codes and labels of most of the training set's anchors and scored on
///     the rest. These labels serve this diagnostic only; the run never sees them. Only the
///     labels are held out: AE1 trained on every anchor's images, so this measures what the
///     code holds of images AE1 has seen (ropes-eval's diagnostic probes measure it on a test
///     set AE1 has not seen, with the protocol's 1,000 calibration samples);
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
  std::string run_dir;                         ///< as given
  std::string config_name;                     ///< run.json's config name ("" when it has none)
  std::string dataset_id;                      ///< the training set's dataset id, from run.json
  std::vector<std::string> joints;             ///< the run's joints, in its latents' order
  std::int64_t train_rows = 0, test_rows = 0;  ///< every regime of their anchors
  std::int64_t train_anchors = 0, test_anchors = 0;  ///< disjoint
  std::uint64_t seed = 0;                            ///< ScreeningOptions::seed
  std::int64_t probe_steps = 0;                      ///< ScreeningOptions::probe_steps
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
/// set at run.json's data_dir, still there (its angles and anchors); the LDR columns come from
/// run.json when stage 2 ran. The test anchors are the first round(test_fraction * anchors) (at
/// least 1) of core::shuffled_indices(anchors, seed, 0); every row of an anchor goes to the same
/// side. Throws std::invalid_argument for options out of range (test_fraction outside (0, 1),
/// probe_steps < 0) or a training set of fewer than 2 anchors; core::FileFormatError naming the
/// file for a run without codes.npy (stage 1 not done), an unreadable run.json, a training set
/// that cannot be opened, is of a sim_dataset_version before 3 (ropes_crl's
/// require_current_sim_dataset) or lacks the columns angles (f32 [n, joints]) and anchor (i64
/// [n]), metadata.joint_names or a joint of the run, and codes that do not match the training
/// set's rows. Cost: reads the
/// codes and the training set's labels, trains the MLP probe (seconds at 3000 steps).
Screening screen_run(const std::filesystem::path& run_dir, const ScreeningOptions& options = {});

}  // namespace ropes::eval
