#include "ropes_eval/calibration.hpp"

#include <gtest/gtest.h>

#include <functional>
#include <limits>
#include <stdexcept>
#include <string>

#include "expect_message.hpp"

namespace ropes::eval {
namespace {

using test_support::expect_message;

// Data and expected values from test/witness_calibration.py (numpy 1.24: polyfit of degree
// 1 and linalg.lstsq on [X, 1]). The joint depends on latents 0 and 1 and, a little,
// non-linearly on latent 0, so the whole-vector fit beats the one-latent fit. Rows 0..29
// calibrate, rows 30..49 test.
Eigen::MatrixXd witness_latents() {
  Eigen::MatrixXd z(50, 3);
  z << 0.034193, 1.359748, 1.224721, -0.510307, -0.297970, -0.527384, 0.569726, -0.056064, 0.746886,
      -1.847325, 1.566549, -0.096432, 0.680378, -0.136566, -0.379099, 0.463110, 0.824514, -0.202530,
      -0.152786, 0.685699, -0.870341, -1.514384, 0.394982, -0.670566, -1.920341, -0.814054,
      -0.467598, -1.193202, -1.492464, 0.036638, 0.897249, -0.233132, -0.743596, 0.384994, 0.717236,
      -0.300011, 0.544668, 1.042875, -0.206956, -0.813516, 0.347651, 0.247546, 1.098813, -1.284581,
      -0.661613, -0.838167, -1.734015, 0.126435, 0.527804, -0.738790, 1.385647, 0.821924, 0.627376,
      0.401707, 0.955670, -1.331980, 0.613930, 0.602777, -1.767719, 0.347030, -0.250421, 0.781523,
      -0.439062, -0.018241, 0.342852, -0.876262, 0.598597, -0.104963, 0.492483, -0.521838, 1.086202,
      0.605202, -0.178025, 0.631957, 1.259755, 1.791176, -1.573576, 0.883132, 0.465069, -0.093861,
      -1.006665, 1.257189, -1.261738, 0.566945, 1.301868, -1.599669, -0.302518, -1.309217, 0.244054,
      1.514375, 2.023556, -1.778114, -0.574949, 0.703545, 1.579373, 0.421211, -0.746152, 0.297132,
      -0.016619, -0.203741, -0.734471, 0.387260, 0.307880, -0.092984, -0.221688, -1.284917,
      -0.486176, 1.206450, -0.190558, -1.439697, 1.334443, 0.530265, 2.108087, 0.062512, -0.461385,
      -1.447645, 1.323838, 2.569512, -0.820935, -0.647088, 0.596189, -0.830345, -0.270558,
      -0.349838, 0.191959, 1.094818, 0.022068, 0.918910, -0.419889, 0.327799, -2.138226, -1.449948,
      0.795913, -0.590149, 0.579915, 0.542344, 1.322279, 0.811859, 1.016991, -0.111671, -0.698285,
      -0.731559, -0.488044, -1.129829, -0.547444, -0.092569, 0.251612, -0.338891, -1.923683,
      -0.072283;
  return z;
}
Eigen::VectorXd witness_joint() {
  Eigen::VectorXd y(50);
  y << 0.063370, 0.082644, 0.771373, -0.997354, 0.813680, 0.581251, 0.096076, -0.518157, -0.406185,
      -0.135280, 1.074470, 0.463779, 0.530340, -0.245715, 1.456927, 0.139045, 0.769954, 0.809157,
      1.289315, 1.118126, -0.048706, 0.249620, 0.816796, -0.239861, 0.067969, 2.194017, 0.643560,
      1.582207, 1.675945, -0.474458, 2.482296, 0.555169, -0.292491, 0.352815, 0.505457, -0.373820,
      0.448308, 0.249517, 0.302403, 2.894376, 0.865472, -0.013330, 0.197313, 0.970063, 0.980140,
      0.445018, 1.059858, 0.028514, -0.110951, 0.482935;
  return y;
}

TEST(CalibrationGolden, AffineFitOfOneLatentMatchesNumpy) {
  const Eigen::MatrixXd z = witness_latents();
  const Eigen::VectorXd y = witness_joint();
  const AffineCalibration a = fit_affine(z.col(0).head(30), y.head(30));
  EXPECT_NEAR(a.scale, 0.72082776662805459, 1e-13);
  EXPECT_NEAR(a.offset, 0.42781854445430867, 1e-13);
  EXPECT_NEAR(calibration_mse(a, z.col(0).tail(20), y.tail(20)), 0.090040473845077892, 1e-13);
}

TEST(CalibrationGolden, LinearFitOfTheWholeLatentMatchesNumpy) {
  const Eigen::MatrixXd z = witness_latents();
  const Eigen::VectorXd y = witness_joint();
  const LinearCalibration fit = fit_linear(z.topRows(30), y.head(30));
  ASSERT_EQ(fit.weights.size(), 3);
  EXPECT_NEAR(fit.weights(0), 0.64174732296623072, 1e-12);
  EXPECT_NEAR(fit.weights(1), -0.23668429149933778, 1e-12);
  EXPECT_NEAR(fit.weights(2), -0.011952444409118849, 1e-12);
  EXPECT_NEAR(fit.offset, 0.40345983331324731, 1e-12);
  EXPECT_NEAR(calibration_mse(fit, z.bottomRows(20), y.tail(20)), 0.037740954715905113, 1e-12);
}

// a dead latent (constant) beside the others: minimum-norm weight 0 there, the same
// predictions as numpy's (which splits it with the offset), the same MSE
TEST(CalibrationGolden, ADeadLatentDoesNotBreakTheWholeLatentFit) {
  Eigen::MatrixXd z(50, 4);
  z << witness_latents(), Eigen::VectorXd::Constant(50, 0.25);
  const Eigen::VectorXd y = witness_joint();
  const LinearCalibration fit = fit_linear(z.topRows(30), y.head(30));
  EXPECT_NEAR(fit.weights(3), 0.0, 1e-12);
  EXPECT_NEAR(calibration_mse(fit, z.bottomRows(20), y.tail(20)), 0.037740954715905009, 1e-12);
}

// the fit is exact for an affine joint, whatever the sign, and the inputs are untouched
TEST(Calibration, RecoversAnExactAffineMapAndLeavesItsInputsAlone) {
  const Eigen::MatrixXd z = witness_latents();
  const Eigen::MatrixXd before = z;
  const Eigen::VectorXd y = -2.5 * z.col(1).array() + 0.75;
  const AffineCalibration a = fit_affine(z.col(1), y);
  EXPECT_NEAR(a.scale, -2.5, 1e-12);
  EXPECT_NEAR(a.offset, 0.75, 1e-12);
  EXPECT_NEAR(calibration_mse(a, z.col(1), y), 0.0, 1e-20);
  const LinearCalibration fit = fit_linear(z, y);
  EXPECT_NEAR(fit.weights(0), 0.0, 1e-12);
  EXPECT_NEAR(fit.weights(1), -2.5, 1e-12);
  EXPECT_NEAR(calibration_mse(fit, z, y), 0.0, 1e-20);
  EXPECT_TRUE((z.array() == before.array()).all());
}

TEST(Calibration, RejectsConstantAndMalformedInputNamingIt) {
  const Eigen::MatrixXd z = witness_latents();
  const Eigen::VectorXd y = witness_joint();
  expect_message([&] { fit_affine(Eigen::VectorXd::Constant(50, 1.0), y); },
                 "fit_affine: the latent is constant (1 in every sample)");
  expect_message([&] { fit_affine(z.col(0), Eigen::VectorXd::Constant(50, 0.5)); },
                 "the joint is constant");
  expect_message([&] { fit_linear(z, Eigen::VectorXd::Constant(50, 0.5)); },
                 "fit_linear: the joint is constant");
  expect_message([&] { fit_affine(z.col(0).head(49), y); },
                 "49 latent samples and 50 joint samples");
  expect_message([&] { fit_linear(z.topRows(1), y.head(1)); }, "at least 2");
  Eigen::MatrixXd bad = z;
  bad(7, 2) = std::numeric_limits<double>::quiet_NaN();
  expect_message([&] { fit_linear(bad, y); }, "latents (7, 2) is nan");
  const LinearCalibration fit = fit_linear(z, y);
  expect_message([&] { calibration_mse(fit, z.leftCols(2), y); },
                 "2 latents a sample, the fit has 3 weights");
}

}  // namespace
}  // namespace ropes::eval
