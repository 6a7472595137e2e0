#include "ropes_eval/pca.hpp"

#include <gtest/gtest.h>

#include <limits>
#include <stdexcept>
#include <string>

#include "expect_message.hpp"

namespace ropes::eval {
namespace {

using test_support::expect_message;

// Data and expected values from test/witness_pca.py (numpy 1.24: linalg.svd of the centred
// samples, each component's largest-magnitude entry made positive).
Eigen::MatrixXd witness_samples() {
  Eigen::MatrixXd x(30, 4);
  x << 3.131716, 1.876111, 3.849773, 0.762982, 1.081013, -0.600823, 2.109401, 3.611820, -1.125477,
      -5.224442, -1.431325, 5.945705, -0.507289, -3.875455, 0.148706, 6.103065, 2.675296, 1.213252,
      2.851450, 1.164613, 0.008551, -4.308846, -0.724203, 4.669640, 0.994007, -3.701204, -1.288143,
      2.161945, 1.440990, -0.501834, 2.466940, 3.450772, -0.786200, -6.326909, -3.314627, 4.502807,
      1.642391, -0.053241, 2.564865, 3.143973, 2.845846, 0.704464, 2.452775, 0.694379, 0.285745,
      -3.328482, -1.769285, 2.455395, 1.571583, -2.206750, 0.498752, 2.650759, 0.341542, 0.124534,
      2.340815, 4.306169, 3.010838, 0.506100, 1.867463, 0.157986, 1.995879, -0.933213, 2.724338,
      2.941239, 1.641998, 0.329074, 2.215200, 2.815806, 2.506770, -0.000119, 2.145848, 1.271886,
      1.684236, 0.605484, 4.480241, 4.316698, 0.264734, -1.650369, 0.635490, 3.905885, 1.231382,
      -2.072934, -0.545461, 1.560567, 0.708196, -1.453973, 0.496342, 3.140168, 1.294204, -2.832804,
      -0.585504, 2.128705, 2.766763, 1.040888, 2.571738, 0.680938, 0.667251, -3.264843, -0.707465,
      3.308769, 0.219839, -2.237659, 0.767162, 4.161379, -0.299351, -5.304086, -2.849106, 3.981309,
      -0.830492, -6.149246, -4.049882, 3.735671, -0.395785, -5.362657, -2.887301, 3.889664,
      0.866365, -2.329549, -0.507704, 2.051998;
  return x;
}

TEST(PcaGolden, ComponentsVariancesAndScoresMatchNumpy) {
  const Eigen::MatrixXd x = witness_samples();
  const Pca p = fit_pca(x, 2);
  ASSERT_EQ(p.components.rows(), 4);
  ASSERT_EQ(p.components.cols(), 2);
  Eigen::MatrixXd expected(4, 2);
  expected.col(0) << 0.32155110735332082, 0.67352272387909295, 0.60613259373691908,
      -0.27490962985696688;
  expected.col(1) << -0.29509506432236826, 0.05948519030721959, 0.46743421965761084,
      0.83119532327833212;
  EXPECT_LT((p.components - expected).cwiseAbs().maxCoeff(), 1e-12) << p.components;
  EXPECT_NEAR(p.variance(0), 12.215697781579161, 1e-11);
  EXPECT_NEAR(p.variance(1), 2.0039583826272596, 1e-11);
  const Eigen::MatrixXd scores = p.project(x);
  EXPECT_NEAR(scores(0, 0), 5.8374575810247364, 1e-11);
  EXPECT_NEAR(scores(0, 1), -0.70295844422013776, 1e-11);
  // the scores are uncorrelated and have the components' variances
  const Eigen::MatrixXd c = scores.transpose() * scores / 29.0;
  EXPECT_NEAR(c(0, 1), 0.0, 1e-10);
  EXPECT_NEAR(c(0, 0), p.variance(0), 1e-10);
}

TEST(Pca, RefusesWhatItCannotFit) {
  const Eigen::MatrixXd x = witness_samples();
  expect_message([&] { fit_pca(x, 5); }, "5 components of 30 samples of 4 values");
  expect_message([&] { fit_pca(x.topRows(1), 1); }, "at least 2 samples");
  Eigen::MatrixXd bad = x;
  bad(3, 1) = std::numeric_limits<double>::infinity();
  expect_message([&] { fit_pca(bad, 1); }, "fit_pca: x (3, 1) is inf");
  expect_message([&] { fit_pca(x, 1).project(x.leftCols(3)); },
                 "samples of 3 values; the fit has 4");
}

}  // namespace
}  // namespace ropes::eval
