#pragma once
/// @file probes.hpp
/// Supervised probes from AE1's code Y to the joint angles, the diagnostics of ropes-eval
/// (repeat 0 of the protocol) and of the screening (screening.hpp): how much of each joint
/// the code holds, linearly and through a small MLP. Labels serve the diagnostic only.
#include <Eigen/Core>

#include <cstdint>
#include <vector>

namespace ropes::eval::detail {

/// The linear probe: ridge regression (lambda 1e-3) of each column of `angles` on [Y, 1]
/// fitted on rows `cal`, Y standardised with the calibration rows' statistics; a column of Y
/// whose sd there is <= 1e-3 of the largest column's is left out (its calibration values
/// carry nothing, and dividing by their tiny spread would blow up the test rows). Returns the
/// test rows' MSE per angle column.
std::vector<double> linear_probe(const Eigen::MatrixXd& y, const Eigen::MatrixXd& angles,
                                 const std::vector<Eigen::Index>& cal,
                                 const std::vector<Eigen::Index>& test);

/// The MLP probe: Y -> 128 -> 128 -> J (ReLU), Y standardised as the linear probe does and
/// each angle column standardised, both with the `cal` rows' statistics; Adam 1e-3 for
/// `steps` batches of 64 of the `cal` rows, drawn by `seed`. Returns the `test` rows' MSE per
/// angle column (rad^2 for angles).
std::vector<double> mlp_probe(const Eigen::MatrixXd& y, const Eigen::MatrixXd& angles,
                              const std::vector<Eigen::Index>& cal,
                              const std::vector<Eigen::Index>& test, std::int64_t steps,
                              std::uint64_t seed);

}  // namespace ropes::eval::detail
