#include "ropes_eval/calibration.hpp"

#include <Eigen/Dense>

#include <cmath>
#include <sstream>
#include <stdexcept>
#include <string>

#include "finite_check.hpp"
#include "ropes_nn/parallel.hpp"

namespace ropes::eval {

namespace {

void check_rows(const char* function, Eigen::Index latent_rows, Eigen::Index joint_rows) {
  if (latent_rows != joint_rows || latent_rows < 2) {
    std::ostringstream message;
    message << function << ": " << latent_rows << " latent samples and " << joint_rows
            << " joint samples; expected the same number, at least 2";
    throw std::invalid_argument(message.str());
  }
}

void check_not_constant(const char* function, const char* name,
                        const Eigen::Ref<const Eigen::VectorXd>& v) {
  if (v.minCoeff() == v.maxCoeff()) {
    std::ostringstream message;
    message << function << ": the " << name << " is constant (" << v(0)
            << " in every sample), so a calibration is undefined";
    throw std::invalid_argument(message.str());
  }
}

}  // namespace

AffineCalibration fit_affine(const Eigen::Ref<const Eigen::VectorXd>& latent,
                             const Eigen::Ref<const Eigen::VectorXd>& joint) {
  check_rows("fit_affine", latent.size(), joint.size());
  detail::require_finite("fit_affine", "latent", latent);
  detail::require_finite("fit_affine", "joint", joint);
  check_not_constant("fit_affine", "latent", latent);
  check_not_constant("fit_affine", "joint", joint);
  const double mx = latent.mean(), my = joint.mean();
  const double sxx = (latent.array() - mx).square().sum();
  AffineCalibration a;
  a.scale = ((latent.array() - mx) * (joint.array() - my)).sum() / sxx;
  a.offset = my - a.scale * mx;
  return a;
}

double calibration_mse(const AffineCalibration& fit,
                       const Eigen::Ref<const Eigen::VectorXd>& latent,
                       const Eigen::Ref<const Eigen::VectorXd>& joint) {
  check_rows("calibration_mse", latent.size(), joint.size());
  detail::require_finite("calibration_mse", "latent", latent);
  detail::require_finite("calibration_mse", "joint", joint);
  return ((fit.scale * latent.array() + fit.offset) - joint.array()).square().mean();
}

LinearCalibration fit_linear(const Eigen::Ref<const Eigen::MatrixXd>& latents,
                             const Eigen::Ref<const Eigen::VectorXd>& joint) {
  // the same blocking of the products below on every CPU (see ropes_nn/parallel.hpp)
  nn::pin_eigen_blocking();
  check_rows("fit_linear", latents.rows(), joint.size());
  detail::require_finite("fit_linear", "latents", latents);
  detail::require_finite("fit_linear", "joint", joint);
  check_not_constant("fit_linear", "joint", joint);
  // centring takes the offset out of the solve; the decomposition's rank threshold drops
  // directions the samples do not span
  const Eigen::RowVectorXd mu = latents.colwise().mean();
  const Eigen::MatrixXd x = latents.rowwise() - mu;
  const double my = joint.mean();
  LinearCalibration fit;
  fit.weights = x.completeOrthogonalDecomposition().solve(Eigen::VectorXd(joint.array() - my));
  fit.offset = my - mu.dot(fit.weights);
  return fit;
}

double calibration_mse(const LinearCalibration& fit,
                       const Eigen::Ref<const Eigen::MatrixXd>& latents,
                       const Eigen::Ref<const Eigen::VectorXd>& joint) {
  check_rows("calibration_mse", latents.rows(), joint.size());
  if (latents.cols() != fit.weights.size()) {
    std::ostringstream message;
    message << "calibration_mse: " << latents.cols() << " latents a sample, the fit has "
            << fit.weights.size() << " weights; expected the same";
    throw std::invalid_argument(message.str());
  }
  detail::require_finite("calibration_mse", "latents", latents);
  detail::require_finite("calibration_mse", "joint", joint);
  return ((latents * fit.weights).array() + fit.offset - joint.array()).square().mean();
}

}  // namespace ropes::eval
