#include "ropes_eval/correlation.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <functional>
#include <limits>
#include <random>
#include <stdexcept>
#include <string>
#include <vector>

#include "expect_message.hpp"

namespace ropes::eval {
namespace {

using test_support::expect_message;

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

// Data and expected values from test/witness_correlation.py (scipy 1.10:
// optimize.linear_sum_assignment on the |pearsonr| and |spearmanr| matrices). Joints 0 and
// 1 are correlated and latent 0 follows both, so greedy matching (largest entry first: joint
// 0 -> latent 0, 0.992) leaves joint 1 with latent 1 (0.679, mean 0.869); the best
// assignment is joint 0 -> latent 1, joint 1 -> latent 0, joint 2 -> latent 3.
Eigen::MatrixXd assignment_angles() {
  Eigen::MatrixXd a(40, 3);
  a << 0.345584, -0.268092, 0.775324, 0.821618, 0.480005, 0.193633, 0.330437, 0.294415, -1.630849,
      -1.303157, -1.775533, -1.195163, 0.905356, 0.856221, 0.883789, 0.446375, 0.494116, 0.679765,
      -0.536953, -0.519160, -0.640243, 0.581118, 0.327972, -0.001049, 0.364572, 0.661446, 0.445574,
      0.294132, 0.739716, 0.468404, 0.028422, 0.188846, 0.876242, 0.546713, 0.137598, 0.256486,
      -0.736454, -0.370628, -0.094828, -0.162910, -0.413630, -0.258848, -0.482119, -0.042539,
      1.055743, 0.598846, 0.062953, -2.250854, 0.039722, 0.496956, -0.138655, -0.292457, -0.302488,
      0.033000, -0.781908, -1.406283, -1.425349, -0.257192, -0.414142, 0.332814, 0.008142, 0.035193,
      -0.651281, -0.275603, -0.139207, 0.862445, 1.294064, 0.802970, -0.125592, 1.006724, 0.453038,
      0.669153, -2.711162, -2.611370, 1.218844, -1.889013, -2.122388, 0.382930, -0.174772,
      -0.057019, -0.875721, -0.422190, -0.042431, -1.514319, 0.213643, -0.610751, 1.753384,
      0.217322, 0.344516, -0.111292, 2.117839, 2.730162, -0.688565, -1.112021, -1.260784, 0.144257,
      -0.377605, -0.783012, -0.191411, 2.042772, 2.418894, 0.852142, 0.646703, 0.773426, 0.033928,
      0.663063, 1.111005, 0.013750, -0.514006, -0.686614, -0.714580, -1.648075, -2.388984, 0.469568,
      0.167465, 0.112459, -1.033867, 0.109014, -0.113900, 0.665889;
  return a;
}
Eigen::MatrixXd assignment_latents() {
  Eigen::MatrixXd z(40, 4);
  z << 0.375243, 0.885324, 1.828430, -0.746605, 0.600827, 0.679620, 2.020073, -0.247174, 0.076610,
      -0.047176, -1.064771, 1.691636, -1.335945, -1.164251, 0.372815, 0.713439, 1.150319, 1.325447,
      -0.673302, -0.340120, 0.355830, 0.844569, -0.023570, -0.860563, -0.658464, 0.646531,
      -1.265637, 0.178346, 0.589386, 0.706619, 1.867146, 0.186701, 0.339875, 0.009126, -0.969180,
      -0.552015, 0.332647, 0.218545, -0.296084, -0.370947, 0.025695, -0.015077, 0.501483, -0.978125,
      0.518090, 0.611955, -0.647561, -0.274408, -0.703819, -0.754471, -0.239312, 0.168560,
      -0.185266, -0.058530, -0.563640, 0.034852, -0.411857, -1.484629, -0.133461, -0.852121,
      0.407200, 1.096624, -1.170543, 2.109884, 0.099186, -0.305121, -0.437988, -0.122251, -0.389503,
      -0.996352, -0.206893, -0.009890, -0.906132, -0.399258, -0.333726, 1.558861, -0.400969,
      0.533203, 0.056690, -0.401537, -0.095737, 0.303959, -0.293102, 0.392525, -0.102628, -0.178907,
      0.753211, -0.676509, 1.190527, 0.734732, -0.323196, -0.402507, 0.890597, 2.729665, -0.136650,
      -0.978412, -2.640050, -2.183007, -0.664781, -1.206987, -1.977774, -2.572590, -0.526515,
      -0.791247, -0.174075, -0.642555, -1.264493, 0.884119, -0.303724, -0.370003, 0.518785,
      1.497860, 0.077006, -0.719196, -1.142518, -1.483762, 0.126831, 0.318500, -0.745856, -0.163145,
      2.323638, 1.842396, 0.359245, 0.500793, -1.200817, -0.376258, 0.402573, -0.044303, -0.564294,
      0.199688, -0.400115, -0.545858, 2.027948, 0.416000, -2.019266, 0.077870, 0.632993, 0.671725,
      0.420513, -0.243523, 0.915382, -0.307417, 0.259563, -0.232700, -0.666082, 0.151776, -1.412381,
      0.972918, -1.780249, -1.547212, 0.770322, -0.481518, -0.057319, 0.496508, -0.701100, 0.500038,
      0.064275, -0.530061, -1.126188, -0.477811;
  return z;
}

TEST(CorrelationGolden, BestAssignmentMatchesScipyWhereGreedyMatchingIsWrong) {
  Eigen::MatrixXd expected(3, 4);
  expected << 0.99192934780901543, 0.79043559148599241, 0.018774304767016636, 0.075200083909131493,
      0.95667779520775642, 0.67938117411823862, 0.057594638279138348, 0.078846427379273942,
      0.028239169739542384, 0.13085240084574293, 0.12839856558906626, 0.93533872620331249;
  const Eigen::MatrixXd c = correlation_matrix(assignment_latents(), assignment_angles());
  ASSERT_EQ(c.rows(), 3);
  ASSERT_EQ(c.cols(), 4);
  EXPECT_LT((c - expected).cwiseAbs().maxCoeff(), 1e-14);
  const Assignment best = best_assignment_correlation(assignment_latents(), assignment_angles());
  EXPECT_EQ(best.latent_of_joint, (std::vector<Eigen::Index>{1, 0, 3}));
  EXPECT_NEAR(best.mean, 0.89415070429902033, 1e-14);
  EXPECT_NEAR(best.correlation(1), expected(1, 0), 1e-15);
  // greedy would have paired joint 0 with latent 0: the best assignment is worth more
  EXPECT_GT(best.mean, (expected(0, 0) + expected(1, 1) + expected(2, 3)) / 3 + 0.02);
  const Assignment rank = best_assignment_correlation(assignment_latents(), assignment_angles(),
                                                      Correlation::kSpearman);
  EXPECT_EQ(rank.latent_of_joint, (std::vector<Eigen::Index>{1, 0, 3}));
  EXPECT_NEAR(rank.mean, 0.84978111319574745, 1e-14);
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

// The Hungarian algorithm against brute force (every injective map of rows to columns) on
// seeded random matrices, square and wide, ties included (weights rounded to 0.1)
TEST(Correlation, BestAssignmentIsTheBestOfEveryAssignment) {
  std::mt19937 rng(7);
  std::uniform_real_distribution<double> uniform(0.0, 1.0);
  for (int trial = 0; trial < 200; ++trial) {
    const Eigen::Index k = 1 + trial % 4, d = k + (trial / 4) % 3;
    Eigen::MatrixXd w(k, d);
    for (Eigen::Index j = 0; j < k; ++j)
      for (Eigen::Index l = 0; l < d; ++l)
        w(j, l) = trial % 2 == 0 ? uniform(rng) : std::round(uniform(rng) * 10) / 10;
    double best = -1;
    std::vector<Eigen::Index> pick(static_cast<std::size_t>(k));
    std::function<void(Eigen::Index, double, std::vector<bool>&)> search =
        [&](Eigen::Index j, double sum, std::vector<bool>& used) {
          if (j == k) {
            best = std::max(best, sum);
            return;
          }
          for (Eigen::Index l = 0; l < d; ++l)
            if (!used[static_cast<std::size_t>(l)]) {
              used[static_cast<std::size_t>(l)] = true;
              search(j + 1, sum + w(j, l), used);
              used[static_cast<std::size_t>(l)] = false;
            }
        };
    std::vector<bool> used(static_cast<std::size_t>(d), false);
    search(0, 0.0, used);
    const Assignment a = best_assignment(w);
    ASSERT_EQ(a.latent_of_joint.size(), static_cast<std::size_t>(k));
    std::vector<bool> taken(static_cast<std::size_t>(d), false);
    double sum = 0;
    for (Eigen::Index j = 0; j < k; ++j) {
      const Eigen::Index l = a.latent_of_joint[static_cast<std::size_t>(j)];
      ASSERT_GE(l, 0);
      ASSERT_LT(l, d);
      EXPECT_FALSE(taken[static_cast<std::size_t>(l)]) << "latent " << l << " assigned twice";
      taken[static_cast<std::size_t>(l)] = true;
      EXPECT_EQ(a.correlation(j), w(j, l));
      sum += w(j, l);
    }
    EXPECT_NEAR(sum, best, 1e-12) << "trial " << trial << ":\n" << w;
    EXPECT_NEAR(a.mean, best / static_cast<double>(k), 1e-12);
  }
  // greedy (largest entry first) takes 0.9 and leaves 0.2; the best is 0.8 + 0.85
  Eigen::MatrixXd w(2, 3);
  w << 0.9, 0.8, 0.1, 0.85, 0.1, 0.2;
  const Assignment a = best_assignment(w);
  EXPECT_EQ(a.latent_of_joint, (std::vector<Eigen::Index>{1, 0}));
  EXPECT_DOUBLE_EQ(a.mean, 0.825);
}

// Perfectly correlated, anti-correlated and permuted latents: the paper's per-joint MCC
// sees the pairing it is given, the best assignment finds the permutation
TEST(Correlation, BestAssignmentUndoesAPermutationOfTheLatents) {
  const Eigen::VectorXd x = witness_x(), y = witness_y();
  Eigen::MatrixXd angles(20, 2), latents(20, 3);
  angles << x, y;
  latents << -3 * y, Eigen::VectorXd::LinSpaced(20, 0, 1), 2 * x + Eigen::VectorXd::Constant(20, 1);
  const Assignment a = best_assignment_correlation(latents, angles);
  EXPECT_EQ(a.latent_of_joint, (std::vector<Eigen::Index>{2, 0}));
  EXPECT_NEAR(a.correlation(0), 1.0, 1e-15);
  EXPECT_NEAR(a.correlation(1), 1.0, 1e-15);
  EXPECT_NEAR(a.mean, 1.0, 1e-15);
  const Eigen::VectorXd paper = per_joint_correlation(latents.leftCols(2), angles);
  EXPECT_NEAR(paper(0), std::abs(pearson(y, x)), 1e-15);
  // inputs are never modified
  EXPECT_TRUE((angles.col(0).array() == x.array()).all());
  EXPECT_TRUE((latents.col(0).array() == (-3 * y).array()).all());
}

TEST(Correlation, BestAssignmentRejectsWhatItCannotScore) {
  const Eigen::VectorXd x = witness_x();
  Eigen::MatrixXd angles(20, 2), latents(20, 2);
  angles << x, witness_y();
  latents << x, Eigen::VectorXd::Constant(20, 0.5);
  expect_message([&] { best_assignment_correlation(latents, angles); },
                 "latent column 1 is constant");
  expect_message([&] { best_assignment_correlation(latents.leftCols(1), angles); },
                 "expected [joints, latents] with 1 <= joints <= latents");
  expect_message([&] { correlation_matrix(latents.topRows(19), angles); },
                 "latents are [19, 2] and angles [20, 2]");
  Eigen::MatrixXd w = Eigen::MatrixXd::Ones(2, 2);
  w(1, 0) = std::numeric_limits<double>::infinity();
  expect_message([&] { best_assignment(w); }, "weight (1, 0) is inf");
  Eigen::MatrixXd bad_angles = angles;
  bad_angles(3, 1) = std::numeric_limits<double>::quiet_NaN();
  expect_message([&] { correlation_matrix(angles, bad_angles); },
                 "joint column 1: value[3] is nan");
}

}  // namespace
}  // namespace ropes::eval
