#include "ropes_crl/bayes_accuracy.hpp"

#include <gtest/gtest.h>

#include <stdexcept>

using ropes::crl::bayes_accuracy;
using ropes::crl::TruncatedNormal;

// Values from witness_bayes_accuracy.py (scipy.stats.truncnorm + scipy.integrate.quad),
// run once with Debian's python3-scipy.
TEST(BayesAccuracy, MatchesScipyQuadrature) {
  struct Case {
    TruncatedNormal p, q;
    double want;
  };
  const Case cases[] = {
      {{-0.75, 0.5, -1.5, 1.5}, {0.75, 0.5, -1.5, 1.5}, 0.9284134566},  // 1C joints 2, 4
      {{2.25, 0.5, 0.0, 3.0}, {0.75, 0.5, 0.0, 3.0}, 0.9284134566},     // 1C joint 6
      {{0.0, 1.0, -2.0, 2.0}, {0.5, 0.3, -1.0, 3.0}, 0.7753986052},     // unequal supports
      {{0.0, 1.0, -1.0, 1.0}, {0.0, 1.0, -1.0, 1.0}, 0.5},              // identical: chance
  };
  for (const Case& c : cases)
    EXPECT_NEAR(bayes_accuracy(c.p, c.q), c.want, 1e-6);
}

TEST(BayesAccuracy, RefusesDegenerateDistributions) {
  EXPECT_THROW(bayes_accuracy({0, 0, -1, 1}, {0, 1, -1, 1}), std::invalid_argument);
  EXPECT_THROW(bayes_accuracy({0, 1, 1, 1}, {0, 1, -1, 1}), std::invalid_argument);
  try {
    TruncatedNormal::from_json({{"mean", 0}, {"std", 1}, {"lower", 0}}, "interventions.j[0]");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("interventions.j[0].upper: missing"), std::string::npos)
        << e.what();
  }
}
