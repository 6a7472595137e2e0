#include "ropes_crl/score_sparsity.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <limits>
#include <stdexcept>
#include <string>

namespace ropes::crl {
namespace {

Eigen::MatrixXd two_samples() {
  Eigen::MatrixXd m(2, 3);
  m << 1.0, -2.0, 0.0,  //
      -3.0, 0.0, 1.0;
  return m;
}

// Witness: worked by hand. E|rows| = (2, 1, 0.5); minus e_1 gives (2, 0, 0.5):
// squared L2 = 4 + 0 + 0.25, L1 = 2 + 0 + 0.5.
TEST(ScoreSparsity, MatchesAHandWorkedExample) {
  const Eigen::MatrixXd m = two_samples();
  EXPECT_TRUE(mean_abs_score_difference(m).isApprox(Eigen::Vector3d(2.0, 1.0, 0.5)));
  EXPECT_DOUBLE_EQ(score_sparsity_loss(m, 1), 4.25);
  EXPECT_DOUBLE_EQ(score_sparsity_loss(m, 1, SparsityNorm::kL1), 2.5);
  // target 0: residual (1, 1, 0.5)
  EXPECT_DOUBLE_EQ(score_sparsity_loss(m, 0), 2.25);
}

// Witness: worked by hand. With the diagonal as |E[Delta s_i]|, target 1: |(-2 + 0) / 2| = 1
// replaces E|Delta s_1| = 1, residual (2, 0, 0.5) as before; target 0: |(1 - 3) / 2| = 1,
// residual (0, 1, 0.5): 1.25 squared, 1.5 in L1.
TEST(ScoreSparsity, TheAbsoluteMeanDiagonalMatchesAHandWorkedExample) {
  const Eigen::MatrixXd m = two_samples();
  const auto abs_mean = SparsityDiagonal::kAbsMean;
  EXPECT_DOUBLE_EQ(score_sparsity_loss(m, 1, SparsityNorm::kL2Squared, abs_mean), 4.25);
  EXPECT_DOUBLE_EQ(score_sparsity_loss(m, 0, SparsityNorm::kL2Squared, abs_mean), 1.25);
  EXPECT_DOUBLE_EQ(score_sparsity_loss(m, 0, SparsityNorm::kL1, abs_mean), 1.5);
  // a latent whose response changes sign across samples is penalised: E|.| = 1, E[.] = 0
  Eigen::MatrixXd folded = Eigen::MatrixXd::Zero(2, 2);
  folded.col(0) << 1.0, -1.0;
  EXPECT_EQ(score_sparsity_loss(folded, 0), 0.0);
  EXPECT_DOUBLE_EQ(score_sparsity_loss(folded, 0, SparsityNorm::kL2Squared, abs_mean), 1.0);
}

TEST(ScoreSparsity, IsZeroExactlyForAOneSparseUnitScoreDifference) {
  Eigen::MatrixXd m = Eigen::MatrixXd::Zero(4, 3);
  m.col(2) << 1.0, -1.0, 0.5, -1.5;  // E|.| = 1 in latent 2 only
  EXPECT_EQ(score_sparsity_loss(m, 2), 0.0);
  EXPECT_EQ(score_sparsity_loss(m, 2, SparsityNorm::kL1), 0.0);
  // the same differences attributed to another latent are not sparse in it
  EXPECT_DOUBLE_EQ(score_sparsity_loss(m, 0), 2.0);
  // leakage into a second latent is penalised
  m(0, 1) = 0.4;
  EXPECT_DOUBLE_EQ(score_sparsity_loss(m, 2), 0.01);
}

TEST(ScoreSparsity, ParsesTheConfigSpellings) {
  EXPECT_EQ(parse_sparsity_norm("l2sq"), SparsityNorm::kL2Squared);
  EXPECT_EQ(parse_sparsity_norm("l1"), SparsityNorm::kL1);
  EXPECT_STREQ(to_string(SparsityNorm::kL1), "l1");
  EXPECT_STREQ(to_string(parse_sparsity_norm("l2sq")), "l2sq");
  EXPECT_EQ(parse_sparsity_diagonal("abs_mean"), SparsityDiagonal::kAbsMean);
  EXPECT_STREQ(to_string(parse_sparsity_diagonal("mean_abs")), "mean_abs");
  // a misspelling is refused, quoted in the message
  const auto expect_refused = [](auto parse, const std::string& spelling) {
    try {
      parse(spelling);
      ADD_FAILURE() << "accepted '" << spelling << "'";
    } catch (const std::invalid_argument& e) {
      EXPECT_NE(std::string(e.what()).find("'" + spelling + "'"), std::string::npos) << e.what();
    }
  };
  expect_refused(parse_sparsity_norm, "L2");
  expect_refused(parse_sparsity_diagonal, "signed");
}

TEST(ScoreSparsity, RejectsBadInputNamingTheProblem) {
  const Eigen::MatrixXd m = two_samples();
  try {
    score_sparsity_loss(m, 3);
    ADD_FAILURE() << "accepted target 3 of 3 latents";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("target latent 3"), std::string::npos) << e.what();
  }
  EXPECT_THROW(score_sparsity_loss(m, -1), std::invalid_argument);
  EXPECT_THROW(score_sparsity_loss(Eigen::MatrixXd(0, 3), 0), std::invalid_argument);
  Eigen::MatrixXd bad = m;
  bad(1, 2) = std::numeric_limits<double>::quiet_NaN();
  try {
    score_sparsity_loss(bad, 0);
    ADD_FAILURE() << "accepted a NaN";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("[1, 2]"), std::string::npos) << e.what();
  }
}

}  // namespace
}  // namespace ropes::crl
