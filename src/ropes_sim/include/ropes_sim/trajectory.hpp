#pragma once
/// @file trajectory.hpp
/// Trajectory: smooth joint-space motion for streaming. The arm moves between successive
/// observational configurations of an InterventionSampler (anchors 0, 1, 2, ... of a seed)
/// along minimum-jerk segments, q(s) = q0 + (q1 - q0)(10 s^3 - 15 s^4 + 6 s^5) with
/// s = t / T, so position, velocity and acceleration are continuous and velocity and
/// acceleration are zero at every target. Sampled at a fixed rate.

#include <cstdint>
#include <vector>

#include "ropes_sim/intervention_sampler.hpp"

namespace ropes::sim {

class Trajectory {
 public:
  struct Point {
    double time;            ///< seconds from the start
    std::vector<double> q;  ///< one angle per joint of the sampler
  };

  /// Throws std::invalid_argument unless segment_seconds > 0 and rate_hz > 0 (finite).
  /// Keeps a reference to `sampler`, which must outlive the trajectory.
  Trajectory(const InterventionSampler& sampler, std::uint64_t seed, double segment_seconds,
             double rate_hz);

  /// The next point: the first at time 0 (the first target), then every 1 / rate_hz.
  Point next();
  /// The configuration at any time t >= 0 (deterministic: the same for any call order).
  std::vector<double> at(double t) const;

 private:
  std::vector<double> target(std::uint64_t k) const;

  const InterventionSampler& sampler_;
  std::uint64_t seed_;
  double segment_, period_;
  std::uint64_t index_ = 0;
};

}  // namespace ropes::sim
