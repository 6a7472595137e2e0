#pragma once
/// @file calibration.hpp
/// Linear calibration of joint angles from latents, as the paper reports its MSE: a least
/// squares fit on labelled calibration samples, its squared error measured on test samples
/// (rad^2 for angles in radians). Two forms: the paper's affine map of joint i from latent i
/// alone, and an affine map of joint i from the whole latent vector.
///
/// Inputs are never modified. A constant joint, or a constant latent in the one-latent fit,
/// is an error (std::invalid_argument naming it), not a NaN.

#include <ropes_crl/calibration.hpp>

#include <Eigen/Core>

namespace ropes::eval {

/// joint ~ scale * latent + offset: ropes_crl's type, the one a run's Calibration holds
using crl::AffineCalibration;

/// Least squares of y on [x, 1], n >= 2 samples. Throws std::invalid_argument when the
/// lengths differ, n < 2, a value is not finite, or x or y is constant (naming which).
AffineCalibration fit_affine(const Eigen::Ref<const Eigen::VectorXd>& latent,
                             const Eigen::Ref<const Eigen::VectorXd>& joint);

/// Mean squared error of `fit` on (latent, joint); the same checks on lengths and values.
double calibration_mse(const AffineCalibration& fit,
                       const Eigen::Ref<const Eigen::VectorXd>& latent,
                       const Eigen::Ref<const Eigen::VectorXd>& joint);

/// joint ~ latents * weights + offset
struct LinearCalibration {
  Eigen::VectorXd weights;
  double offset = 0;
};

/// Least squares of y on [X, 1] (X: [n, d], one sample a row), solved by a complete
/// orthogonal decomposition: a latent that is constant or a combination of others (a dead
/// latent of an overcomplete AE2) gets the minimum-norm weight and does not break the fit.
/// Throws std::invalid_argument when the row counts differ, n < 2, a value is not finite,
/// or y is constant.
LinearCalibration fit_linear(const Eigen::Ref<const Eigen::MatrixXd>& latents,
                             const Eigen::Ref<const Eigen::VectorXd>& joint);

/// Mean squared error of `fit` on (latents, joint); checks shapes and values.
double calibration_mse(const LinearCalibration& fit,
                       const Eigen::Ref<const Eigen::MatrixXd>& latents,
                       const Eigen::Ref<const Eigen::VectorXd>& joint);

}  // namespace ropes::eval
