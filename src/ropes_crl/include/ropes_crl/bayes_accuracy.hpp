#pragma once
/// @file bayes_accuracy.hpp
/// The best accuracy any classifier can reach when telling two truncated normal
/// distributions apart with equal priors: 1/2 * integral of max(p1, p2). What each joint's
/// LDR held-out accuracy is compared with (the classifier sees the images, which are a
/// function of all joints; only joint i differs between the two interventions).
#include <nlohmann/json.hpp>

namespace ropes::crl {

/// N(mean, std^2) truncated to [lower, upper].
struct TruncatedNormal {
  double mean = 0, std = 1, lower = -1, upper = 1;
  /// Reads {"mean", "variance" or "std", "lower", "upper"} (the dataset manifest's
  /// distribution entries; the paper's TN(mean, x) takes the variance x, std = sqrt(x)).
  /// Throws std::invalid_argument naming `where` and the field, also when both or neither
  /// of variance and std are given.
  static TruncatedNormal from_json(const nlohmann::json& j, const std::string& where);
  /// The density at x (0 outside [lower, upper]).
  double pdf(double x) const;
};

/// 1/2 * integral max(p(x), q(x)) dx by composite Simpson on 20,000 intervals on each piece
/// between the supports' ends (where the densities jump); within 1e-6 of scipy's quad in the
/// tests. Throws std::invalid_argument for std <= 0 or lower >= upper.
double bayes_accuracy(const TruncatedNormal& p, const TruncatedNormal& q);

}  // namespace ropes::crl
