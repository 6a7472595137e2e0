#pragma once
/// @file bayes_accuracy.hpp
/// The best accuracy any classifier can reach when telling two truncated normal
/// distributions apart with equal priors: 1/2 * integral of max(p1, p2). What each joint's
/// LDR held-out accuracy is compared with (the classifier sees the images, which are a
/// function of all joints; only joint i differs between the two interventions).
#include <ropes_core/truncated_normal.hpp>

#include <nlohmann/json.hpp>

#include <string>

namespace ropes::crl {

using core::TruncatedNormal;

/// The truncated normal of a dataset manifest's distribution entry {"mean", "variance" or
/// "std", "lower", "upper"} (the paper's TN(mean, x) takes the variance x, std = sqrt(x)).
/// Throws std::invalid_argument naming `where` and the field, also when both or neither of
/// variance and std are given or the values make no distribution.
TruncatedNormal truncated_normal_from_json(const nlohmann::json& j, const std::string& where);

/// 1/2 * integral max(p(x), q(x)) dx by composite Simpson on 20,000 intervals on each piece
/// between the supports' ends (where the densities jump); within 1e-6 of scipy's quad in the
/// tests.
double bayes_accuracy(const TruncatedNormal& p, const TruncatedNormal& q);

}  // namespace ropes::crl
