#pragma once
/// @file intervention_sampler.hpp
/// InterventionSampler: the paper's joint-angle distributions (observational, two hard
/// interventions per joint, optionally a linear causal model) read from a config file, and
/// the samples of one anchor: the observational configuration and, for each intervened
/// joint, two configurations in which only that joint (and, under a causal model, its
/// descendants) changed.
///
/// Config files (share/ropes_sim/distributions/*.json, transcribed from the paper's tables,
/// each naming its table in "source"):
///   joints         the robot's coordinates in order, e.g. panda_joint1 .. panda_joint7
///   held           joints fixed at a value in every sample
///   observational  joint -> {mean, variance, lower, upper}: the paper's
///                  TN_[lower, upper](mean, variance), variance as the paper defines it (its
///                  line 472; DESIGN.md); {mean, std, lower, upper} gives a standard
///                  deviation instead. Exactly one of variance and std.
///   interventions  joint -> [two TN distributions]: the joints intervened on, in order
///   sem            optional: {noise: TN, parents: joint -> {parent: weight}}; a joint
///                  without parents that has an observational TN is a root: root = TN draw
///                  + noise, other = sum(weight * parent) + noise. An intervention sets the
///                  joint to its draw and recomputes its descendants with the same noise.

#include <cstdint>
#include <filesystem>
#include <optional>
#include <string>
#include <vector>

#include "ropes_core/file_format_error.hpp"
#include "ropes_sim/truncated_normal.hpp"

namespace ropes::sim {

/// Thrown for a config file that cannot be used; the message names the file and the field.
/// ropes_core's, the one config error of the workspace.
using core::ConfigError;

class InterventionSampler {
 public:
  /// Reads and checks a config file: every joint named must be in "joints", every TN valid
  /// (lower < upper, variance or std > 0, exactly one of them), each intervened joint has exactly
  /// two distributions, and every joint is held, observational or (with a sem) a child in the sem.
  static InterventionSampler load(const std::filesystem::path& path);

  const std::string& name() const { return name_; }
  const std::vector<std::string>& joint_names() const { return joints_; }
  /// "observational", then "do(<joint>)=1", "do(<joint>)=2" per intervened joint.
  const std::vector<std::string>& regime_names() const { return regimes_; }
  /// Indices into joint_names() of the intervened joints, in regime order.
  const std::vector<int>& intervened_joints() const { return intervened_; }
  /// What regime r is, parsed: the intervened joint (an index into joint_names(); -1 for the
  /// observational regime) and which of its two interventions (1 or 2; 0 when observational).
  struct Regime {
    int joint = -1;
    int intervention = 0;
  };
  /// One per regime_names() entry, in the same order.
  const std::vector<Regime>& regimes() const { return regime_info_; }

  /// The configurations of anchor `anchor` under `seed`, one per regime (regime_names()
  /// order), each with one angle per joint. Draws come from PhiloxStream(seed, anchor)
  /// alone, so an anchor's samples do not depend on any other anchor.
  std::vector<std::vector<double>> sample_anchor(std::uint64_t seed, std::uint64_t anchor) const;

  /// The observational distribution of joint `j` (nullopt for held and non-root sem joints).
  const std::optional<TruncatedNormal>& observational(int j) const;
  const std::vector<TruncatedNormal>& interventions(int j) const;
  /// The sem weight of `parent` in `child` (0 when none).
  double sem_weight(int child, int parent) const;
  /// The sem's noise distribution (nullopt without a sem).
  const std::optional<TruncatedNormal>& sem_noise() const { return sem_noise_; }

 private:
  struct JointSpec {
    std::optional<double> held;
    std::optional<TruncatedNormal> observational;
    std::vector<TruncatedNormal> interventions;
    std::vector<std::pair<int, double>> parents;  // sem
  };
  // observational values and the sem noise of one anchor
  void draw_observational(core::PhiloxStream& rng, std::vector<double>* q,
                          std::vector<double>* noise) const;
  // recomputes the sem children of joint `changed` (and theirs) in joint order
  void propagate(int changed, const std::vector<double>& noise, std::vector<double>* q) const;

  std::string name_;
  std::vector<std::string> joints_;
  std::vector<JointSpec> specs_;
  std::optional<TruncatedNormal> sem_noise_;
  std::vector<int> intervened_;
  std::vector<std::string> regimes_;
  std::vector<Regime> regime_info_;
};

}  // namespace ropes::sim
