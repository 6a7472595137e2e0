#include "ropes_eval/correlation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <stdexcept>
#include <string>

namespace ropes::eval {
namespace {

// Data and expected values from test/witness_correlation.py (scipy.stats 1.10:
// pearsonr, spearmanr, rankdata). y has ties, so Spearman exercises average ranks.
Eigen::VectorXd witness_x() {
  Eigen::VectorXd x(20);
  x << 0.0, 0.8414709848078965, 0.9092974268256816, 0.1411200080598672, -0.7568024953079284,
      -0.9589242746631386, -0.2794154981989259, 0.6569865987187891, 0.9893582466233817,
      0.4121184852417566, -0.5440211108893698, -0.9999902065507034, -0.5365729180004348,
      0.4201670368266409, 0.9906073556948702, 0.6502878401571168, -0.28790331666506536,
      -0.961397491879557, -0.7509872467716763, 0.14987720966295234;
  return x;
}
Eigen::VectorXd witness_y() {
  Eigen::VectorXd y(20);
  y << 0.3, 0.3, 1.0, -0.3, -0.2, -1.1, 0.2, 0.1, 1.1, -0.0, -0.1, -1.0, -0.2, 0.2, 0.9, 0.4, -0.2,
      -0.7, -0.7, 0.3;
  return y;
}

TEST(CorrelationGolden, PearsonAndSpearmanMatchScipy) {
  EXPECT_NEAR(pearson(witness_x(), witness_y()), 0.87835408284935468, 1e-14);
  EXPECT_NEAR(spearman(witness_x(), witness_y()), 0.87849682093234871, 1e-14);
}

TEST(CorrelationGolden, AverageRanksMatchScipyRankdata) {
  Eigen::VectorXd expected(20);
  expected << 15.0, 15.0, 19.0, 5.0, 7.0, 1.0, 12.5, 11.0, 20.0, 10.0, 9.0, 2.0, 7.0, 12.5, 18.0,
      17.0, 7.0, 3.5, 3.5, 15.0;
  EXPECT_EQ(average_ranks(witness_y()), expected);
}

TEST(Correlation, SpearmanIsInvariantUnderMonotonicMapsPearsonIsNot) {
  const Eigen::VectorXd x = witness_x();
  const Eigen::VectorXd cubed = x.array().cube();
  EXPECT_DOUBLE_EQ(spearman(x, cubed), 1.0);
  EXPECT_LT(pearson(x, cubed), 0.99);
  EXPECT_DOUBLE_EQ(pearson(x, -2.0 * x), -1.0);
}

TEST(Correlation, PerJointTakesAbsoluteValuesColumnByColumn) {
  const Eigen::VectorXd x = witness_x();
  Eigen::MatrixXd latents(20, 2), angles(20, 2);
  latents << -3.0 * x, witness_y();
  angles << x, x;
  const Eigen::VectorXd pearson_mcc = per_joint_correlation(latents, angles);
  EXPECT_DOUBLE_EQ(pearson_mcc(0), 1.0);
  EXPECT_NEAR(pearson_mcc(1), 0.87835408284935468, 1e-14);
  const Eigen::VectorXd spearman_mcc =
      per_joint_correlation(latents, angles, Correlation::kSpearman);
  EXPECT_NEAR(spearman_mcc(1), 0.87849682093234871, 1e-14);
}

void expect_message(const std::function<void()>& call, const std::string& needle) {
  try {
    call();
    ADD_FAILURE() << "no exception; expected one containing '" << needle << "'";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find(needle), std::string::npos) << e.what();
  }
}

TEST(Correlation, RejectsBadInputNamingTheProblem) {
  const Eigen::VectorXd x = witness_x();
  expect_message([&] { pearson(x, x.head(19)); }, "lengths 20 and 19");
  expect_message([&] { spearman(x.head(1), x.head(1)); }, "at least 2");
  expect_message([&] { pearson(x, Eigen::VectorXd::Constant(20, 0.1)); }, "y is constant");
  Eigen::VectorXd with_nan = x;
  with_nan(4) = std::numeric_limits<double>::quiet_NaN();
  expect_message([&] { pearson(with_nan, x); }, "x[4] is nan");
  expect_message([&] { per_joint_correlation(Eigen::MatrixXd(5, 2), Eigen::MatrixXd(5, 3)); },
                 "latents are [5, 2] but angles are [5, 3]");
  Eigen::MatrixXd latents(20, 2), angles(20, 2);
  latents << x, Eigen::VectorXd::Zero(20);
  angles << x, x;
  expect_message([&] { per_joint_correlation(latents, angles); }, "joint column 1: x is constant");
}

}  // namespace
}  // namespace ropes::eval
