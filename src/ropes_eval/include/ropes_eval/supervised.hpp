#pragma once
/// @file supervised.hpp
/// The supervised label-efficiency baseline: the role RoboPEPP plays in the paper, in our
/// own framework. The same encoder architecture as ROPES — AE1's encoder, then AE2's encoder
/// (the run's Ae2Spec) — trained with joint-angle labels on a seeded fraction of the run's
/// training set: its first J outputs regress the J joints (standardised), mean squared error,
/// Adam. AE1's encoder is the run's, frozen (it was trained without labels, so the baseline
/// sees exactly the labels it is given); what is trained with labels is the AE2 encoder, from
/// a fresh initialisation. The epochs follow the paper's RoboPEPP schedule (100, 75, 25 and
/// 15 epochs at 1, 5, 10 and 100 % of the labels; other fractions: 15 / sqrt(fraction) capped
/// at 100).
#include <Eigen/Core>

#include <cstdint>
#include <filesystem>
#include <memory>
#include <string>
#include <vector>

namespace ropes::eval {

struct SupervisedOptions {
  std::int64_t batch_size = 64;
  double lr = 1e-3;
  std::uint64_t seed = 0;  ///< which samples are labelled, the initialisation, the batches
  /// epochs over the labelled samples; 0: the paper's schedule (see above)
  std::int64_t epochs = 0;
  /// an upper bound on the optimiser steps (0: none), for tests
  std::int64_t max_steps = 0;
};

/// The method name a supervised baseline is scored under: "supervised_<p>%" with p the
/// percentage of labelled rows as %g prints it (0.05 -> "supervised_5%").
std::string supervised_method_name(double fraction);

class SupervisedEncoder {
 public:
  /// Trains on `fraction` (0 < fraction <= 1) of the rows of the run's training set
  /// (RUN/codes.npy and the angles of run.json's data_dir): the first round(fraction * rows)
  /// of core::shuffled_indices(rows, seed, 0), at least 2, so smaller fractions are subsets of
  /// larger ones. Throws std::invalid_argument for a fraction outside (0, 1];
  /// core::FileFormatError for an unreadable run or training set, or one of fewer than 2 rows.
  static SupervisedEncoder train(const std::filesystem::path& run_dir, double fraction,
                                 const SupervisedOptions& options = {});
  SupervisedEncoder(SupervisedEncoder&&) noexcept;
  SupervisedEncoder& operator=(SupervisedEncoder&&) noexcept;
  ~SupervisedEncoder();

  /// AE1 codes Y, flattened [n, C*8*8] as evaluate_run holds them -> joint angles [n, J]
  /// (radians, the run's joints).
  Eigen::MatrixXd predict(const Eigen::MatrixXd& codes) const;
  double fraction() const;
  const std::vector<std::string>& joints() const;  ///< what predict's columns are
  std::int64_t labels() const;                     ///< labelled samples it trained on
  std::int64_t steps() const;                      ///< optimiser steps it took
  double final_loss() const;  ///< the mean loss of its last epoch (standardised units)

 private:
  struct State;
  explicit SupervisedEncoder(std::unique_ptr<State> state);
  std::unique_ptr<State> state_;
};

}  // namespace ropes::eval
