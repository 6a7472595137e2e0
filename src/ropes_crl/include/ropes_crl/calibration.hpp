#pragma once
/// @file calibration.hpp
/// The calibration of a run's latents to joint angles: the one calibration type of the
/// workspace, and where a run's calibrations are kept.
///
/// The latents identify each joint up to a monotonic map (the paper: close to affine), so
/// angles need an affine fit of joint k from latent k on a few labelled samples. ropes-eval
/// fits one (repeat 0 of the paper's protocol) and writes it, as calibration.json, into its
/// own output, never into the run directory; ropes-stream and Estimator users read it.
///
///   calibration.json   {"format": "ropes-calibration", "joints": [...], "scale": [...],
///                       "offset": [...], "run": {"config", "config_sha256", "seed",
///                       "dataset"}}: the fit and the run it was fitted for
#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

namespace ropes::crl {

class RunDirectory;

/// joint ~ scale * latent + offset: the paper's calibration of one joint from one latent.
struct AffineCalibration {
  double scale = 0, offset = 0;
};

/// Which run a calibration was fitted for. A seed gives the same bytes (DESIGN.md), so the
/// config (its name and the SHA-256 of run.json's copy of it), the seed and the training
/// set's id determine the weights.
struct RunIdentity {
  std::string config, config_sha256, dataset;
  std::uint64_t seed = 0;
  static RunIdentity of(const RunDirectory& run);
  bool operator==(const RunIdentity& other) const;
  bool operator!=(const RunIdentity& other) const { return !(*this == other); }
  /// "config 1c-small (sha256 1a2b3c4d5e6f...), seed 0, dataset 9f8e7d6c5b4a..."
  std::string describe() const;
};

/// angle_k = scale[k] * latent_k + offset[k] for the run's joints, in latent order.
struct Calibration {
  std::vector<std::string> joints;
  std::vector<double> scale, offset;
  /// The run it was fitted for; nullopt in a file written before it was recorded (such a
  /// file is accepted for any run with the same joints).
  std::optional<RunIdentity> run;

  /// Joint k's fit. Throws std::out_of_range for k >= joints.size().
  AffineCalibration joint(std::size_t k) const;
  nlohmann::json to_json() const;
  /// Throws std::invalid_argument naming the field ("calibration.scale: expected 3
  /// numbers, got ...").
  static Calibration from_json(const nlohmann::json& j);
  /// Reads calibration.json. Throws core::FileFormatError naming the file and the field.
  static Calibration read(const std::filesystem::path& file);
  /// Writes to_json() to `file` atomically (core::write_file_atomically).
  void write(const std::filesystem::path& file) const;
  /// Throws std::invalid_argument, naming both, when it was fitted for another run: its
  /// joints differ from the run's, or its recorded run is not `run`'s identity.
  void check_fits(const RunDirectory& run) const;
};

/// Where ropes-eval writes a run's evaluation when told nowhere else: the directory beside
/// the run, named after it with "-eval" (runs/a/ -> runs/a-eval). Never inside the run. The
/// name is the path's as given: a run reached through a link (runs/latest) has its
/// evaluations beside the link (runs/latest-eval), so give ropes-eval and ropes-stream the
/// same path, or ropes-stream --calibration.
std::filesystem::path default_evaluation_dir(const std::filesystem::path& run_dir);

/// Where an evaluation of the run in `run_dir` writes `name`: `out` when not empty, else
/// default_evaluation_dir(run_dir) / name. Throws std::invalid_argument when `out` lies inside
/// the run directory (after resolving links): an evaluation never writes into a run.
std::filesystem::path evaluation_output(const std::filesystem::path& run_dir,
                                        const std::filesystem::path& out,
                                        const std::filesystem::path& name);

/// The calibrations of `run` that its evaluations may have written, in this order:
/// default_evaluation_dir(run)/calibration.json (ropes-eval --data),
/// default_evaluation_dir(run)/report/calibration.json (ropes-eval --suite) and, when the
/// run is ropes-run's OUT/run (OUT holds ropes-run.json), OUT/report/calibration.json.
std::vector<std::filesystem::path> calibration_candidates(const RunDirectory& run);

/// The run's latest evaluation's calibration: of calibration_candidates() that exist and
/// record this run (check_fits), the most recently written one; nullopt when there is none.
/// A candidate that cannot be read or was fitted for another run is passed over, and
/// `skipped` (when not null) gets a line naming it and why.
std::optional<std::filesystem::path> latest_calibration(
    const RunDirectory& run, std::vector<std::string>* skipped = nullptr);

}  // namespace ropes::crl
