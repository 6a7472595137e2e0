#include "ropes_sim/trajectory.hpp"

#include <cmath>
#include <stdexcept>
#include <string>

namespace ropes::sim {

Trajectory::Trajectory(const InterventionSampler& sampler, std::uint64_t seed,
                       double segment_seconds, double rate_hz)
    : sampler_(sampler), seed_(seed), segment_(segment_seconds), period_(0.0) {
  if (!(segment_seconds > 0) || !std::isfinite(segment_seconds) || !(rate_hz > 0) ||
      !std::isfinite(rate_hz)) {
    throw std::invalid_argument("Trajectory: segment_seconds=" + std::to_string(segment_seconds) +
                                " rate_hz=" + std::to_string(rate_hz) +
                                "; expected both finite and > 0");
  }
  period_ = 1.0 / rate_hz;
}

std::vector<double> Trajectory::target(std::uint64_t k) const {
  return sampler_.sample_anchor(seed_, k)[0];
}

std::vector<double> Trajectory::at(double t) const {
  if (!(t >= 0) || !std::isfinite(t)) {
    throw std::invalid_argument("Trajectory::at: t=" + std::to_string(t) + "; expected >= 0");
  }
  const auto k = static_cast<std::uint64_t>(std::floor(t / segment_));
  const double s = t / segment_ - static_cast<double>(k);
  const double blend = s * s * s * (10.0 - 15.0 * s + 6.0 * s * s);
  const std::vector<double> q0 = target(k), q1 = target(k + 1);
  std::vector<double> q(q0.size());
  for (std::size_t j = 0; j < q.size(); ++j)
    q[j] = q0[j] + (q1[j] - q0[j]) * blend;
  return q;
}

Trajectory::Point Trajectory::next() {
  const double t = static_cast<double>(index_++) * period_;
  return {t, at(t)};
}

}  // namespace ropes::sim
