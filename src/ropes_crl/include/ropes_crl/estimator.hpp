#pragma once
/// @file estimator.hpp
/// Estimator: a trained run's images -> latents -> joint angles.
///
/// Loads AE1, the AE2 model(s) and the LDRs of a run directory written by ropes-train (see
/// trainer.hpp). Latent k of the estimate is joint k of the run's config (config.joints):
/// in per_joint mode latent k of joint k's AE2, in joint mode latent k of the one AE2. The
/// latents identify each joint up to a monotonic map (the paper: close to affine), so
/// angles need a Calibration (calibration.hpp), fitted on a few labelled samples (ropes-eval
/// fits one).
///
/// Not thread-safe: one Estimator per thread. Cost per frame at the `small` preset: one AE1
/// encoder pass and one AE2 encoder pass per joint (see ropes_crl_bench).
#include "ropes_crl/calibration.hpp"
#include "ropes_crl/experiment_config.hpp"
#include "ropes_crl/networks.hpp"
#include "ropes_crl/run_directory.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace ropes::crl {

class Estimator {
 public:
  /// Loads the run in `run_dir`. Throws FileFormatError naming the file when the run is
  /// incomplete (run.json not "complete"), a weight file is missing or does not match the
  /// architecture its metadata and the run's config describe.
  static Estimator load(const std::filesystem::path& run_dir);
  /// The same from a run directory already opened (reads no run.json again).
  static Estimator load(const RunDirectory& run);
  Estimator(Estimator&&) noexcept;
  Estimator& operator=(Estimator&&) noexcept;
  ~Estimator();

  const ExperimentConfig& config() const;
  const std::vector<std::string>& joints() const { return config().joints; }
  std::int64_t cameras() const { return config().cameras; }
  std::int64_t image_size() const { return config().image_size; }

  /// images [n, cameras, S, S] in [0, 1] -> Y [n, C, 8, 8]. Throws std::invalid_argument
  /// naming both shapes when the images are not [n, cameras, S, S].
  Tensor codes(const Tensor& images);
  /// Y [n, C, 8, 8] -> latents [n, J], J = joints().size().
  Tensor latents_from_codes(const Tensor& y);
  /// images -> latents: codes() then latents_from_codes().
  Tensor latents(const Tensor& images);
  /// Every AE2 latent (d of them) of the model that estimates joint k: [n, d].
  Tensor full_latents_from_codes(const Tensor& y, std::size_t joint);
  /// Baseline: LDR_k(y) of each joint, [n, J] (a log density ratio, monotonic in joint k for
  /// the paper's shifted-mean interventions).
  Tensor ldr_logits_from_codes(const Tensor& y);
  /// Baseline: latent k of the lambda = 0 AE2, [n, J]. Throws std::logic_error when the run
  /// trained none (has_lambda0() false).
  Tensor lambda0_latents_from_codes(const Tensor& y);
  bool has_lambda0() const;

  /// AE1's reconstruction of `images` [n, cameras, S, S]: decode(encode(x)), each camera's
  /// image on its own, [n, cameras, S, S] (values as the decoder gives them, not clamped).
  Tensor reconstruct(const Tensor& images);
  /// The paper's occlusion figure's last panel: the code Y of `images`, reconstructed by the
  /// AE2 that estimates joint `joint` (back to Y's coordinates when it reads standardised
  /// codes; 0 stays where the map dropped an element) and decoded by AE1's decoder:
  /// [n, cameras, S, S]. Throws std::invalid_argument for a joint out of range.
  Tensor reconstruct_through_ae2(const Tensor& images, std::size_t joint);

  void set_calibration(const Calibration& calibration);
  bool calibrated() const;
  /// latents [n, J] -> angles [n, J] with the calibration. std::logic_error without one.
  Tensor angles_from_latents(const Tensor& latents) const;

  /// One frame: `pixels` holds cameras * S * S bytes (camera-major, row-major), the layout of
  /// a dataset row and of a streamed frame. Writes J latents and, when calibrated and
  /// `angles` is not null, J angles. After a few warm-up calls it allocates nothing from the
  /// system (ropes_nn's pool and per-thread workspaces are reused). The latents are those of
  /// latents() on a batch of this one frame, bit for bit; inside a larger batch they agree to
  /// float rounding (the MLP's products become a GEMM).
  void estimate_frame(const std::uint8_t* pixels, float* latents, float* angles = nullptr);

 private:
  struct State;
  explicit Estimator(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace ropes::crl
