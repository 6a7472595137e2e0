// The linear probe (probes.hpp) of ropes-eval's diagnostics on a code element that barely varies.
#include "ropes_eval/probes.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <vector>

using ropes::eval::detail::linear_probe;

// Column 2 of Y is constant on the calibration rows up to 1e-6 (float noise of an AE1 code
// element over a static background) and moves by 0.05 on the test rows. Standardising it
// with its calibration spread made the test rows' design values ~6e4 and the probe's MSE
// absurd (hundreds of rad^2 on a validation set); it must be left out. The witness: the same
// probe on Y without that column, which must give the same MSE.
TEST(LinearProbe, LeavesOutAnElementThatDoesNotVaryOnTheCalibrationRows) {
  const Eigen::Index n = 200;
  Eigen::MatrixXd y(n, 3), angles(n, 1);
  std::vector<Eigen::Index> cal, test;
  for (Eigen::Index r = 0; r < n; ++r) {
    const double a = std::sin(0.37 * static_cast<double>(r)), b = std::cos(1.3 * r + 0.2);
    y(r, 0) = a;
    y(r, 1) = b;
    const bool calibration = r % 2 == 0;
    y(r, 2) = 0.5 + (calibration ? 1e-6 * ((r / 2) % 3) : 0.05);
    angles(r, 0) = 0.8 * a - 0.3 * b + 0.01 * std::sin(7.1 * r);
    (calibration ? cal : test).push_back(r);
  }
  const std::vector<double> with = linear_probe(y, angles, cal, test);
  const Eigen::MatrixXd two = y.leftCols(2);
  const std::vector<double> without = linear_probe(two, angles, cal, test);
  ASSERT_EQ(with.size(), 1u);
  EXPECT_LT(without[0], 1e-3);  // the two varying columns explain the angle
  EXPECT_NEAR(with[0], without[0], 1e-12);
}
