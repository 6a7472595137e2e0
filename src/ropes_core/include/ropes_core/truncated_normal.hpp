#pragma once
/// @file truncated_normal.hpp
/// TruncatedNormal: the TN_[a,b](mu, sigma^2) distribution of the ROPES paper's sampling tables:
/// what ropes_sim samples the joints from and ropes_crl computes the Bayes accuracy of an
/// intervention pair with.

#include "ropes_core/philox.hpp"

namespace ropes::core {

/// The normal distribution N(mu, sigma^2) conditioned on the closed interval [lower, upper].
///
/// `sigma` is a standard deviation. The paper writes TN_[a,b](mu, sigma^2) and defines the
/// second parameter as the variance (its line 472), so distribution files state the paper's
/// number as `variance` and InterventionSampler::load passes sigma = sqrt(variance); a file
/// may give `std` instead (DESIGN.md, "Decisions").
///
/// Sampling is by inversion: one uniform_double() per sample, mapped through the quantile
/// function, so a stream's position after n samples is always 2n words. Works far into the
/// tails: an interval entirely in the upper tail is handled by symmetry on the lower tail,
/// where the normal CDF keeps its relative precision.
class TruncatedNormal {
 public:
  /// Throws std::invalid_argument, naming the values, when a value is not finite, when
  /// sigma <= 0, when lower >= upper, or when [lower, upper] lies entirely more than 37 sigma
  /// from mu (where the normal density underflows double precision).
  TruncatedNormal(double mu, double sigma, double lower, double upper);

  /// One draw; advances `rng` by one uniform_double() (two 32-bit words).
  double sample(PhiloxStream& rng) const;

  /// The u-quantile, u in [0, 1]: quantile(0) == lower, quantile(1) == upper.
  /// Throws std::invalid_argument for u outside [0, 1].
  double quantile(double u) const;

  /// P(X <= x); 0 below lower, 1 above upper.
  double cdf(double x) const;
  /// Density; 0 outside [lower, upper].
  double pdf(double x) const;

  /// Closed-form mean and variance of the truncated distribution.
  double mean() const;
  double variance() const;

  double mu() const { return mu_; }
  double sigma() const { return sigma_; }
  double lower() const { return lower_; }
  double upper() const { return upper_; }

 private:
  double mu_, sigma_, lower_, upper_;
  bool flipped_;                 // sample -X on [-upper, -lower] (interval in the upper tail)
  double alpha_, beta_;          // standardised bounds, after the flip when flipped_
  double cdf_alpha_, cdf_beta_;  // Phi(alpha_), Phi(beta_)
};

/// The standard normal quantile Phi^-1(p) for p in (0, 1), to about 1e-15 relative error
/// (Acklam's rational approximation followed by one Halley step on erfc). Returns -inf and
/// +inf at 0 and 1.
double standard_normal_quantile(double p);

}  // namespace ropes::core
