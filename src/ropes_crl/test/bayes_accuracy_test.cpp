#include "ropes_crl/bayes_accuracy.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <stdexcept>
#include <string>

using ropes::crl::bayes_accuracy;
using ropes::crl::truncated_normal_from_json;
using ropes::crl::TruncatedNormal;

// Values from witness_bayes_accuracy.py (scipy.stats.truncnorm + scipy.integrate.quad),
// run once with Debian's python3-scipy.
TEST(BayesAccuracy, MatchesScipyQuadrature) {
  struct Case {
    TruncatedNormal p, q;
    double want;
  };
  const Case cases[] = {
      // 1C joints 2, 4 and 6: the paper's variance 0.5, then the old reading as std 0.5
      {{-0.75, std::sqrt(0.5), -1.5, 1.5}, {0.75, std::sqrt(0.5), -1.5, 1.5}, 0.8319103700},
      {{2.25, std::sqrt(0.5), 0.0, 3.0}, {0.75, std::sqrt(0.5), 0.0, 3.0}, 0.8319103700},
      {{-0.75, 0.5, -1.5, 1.5}, {0.75, 0.5, -1.5, 1.5}, 0.9284134566},
      {{2.25, 0.5, 0.0, 3.0}, {0.75, 0.5, 0.0, 3.0}, 0.9284134566},
      // 2C joint 4, variance 0.4
      {{0.9, std::sqrt(0.4), -1.5, 1.5}, {-0.9, std::sqrt(0.4), -1.5, 1.5}, 0.9067142150},
      {{0.0, 1.0, -2.0, 2.0}, {0.5, 0.3, -1.0, 3.0}, 0.7753986052},  // unequal supports
      {{0.0, 1.0, -1.0, 1.0}, {0.0, 1.0, -1.0, 1.0}, 0.5},           // identical: chance
  };
  for (const Case& c : cases)
    EXPECT_NEAR(bayes_accuracy(c.p, c.q), c.want, 1e-6);
}

// what `f` throws as std::invalid_argument ("" when nothing)
template <typename F>
std::string message_of(F f) {
  try {
    f();
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}

// a manifest's entry states the paper's variance (or a std), never both
TEST(BayesAccuracy, ReadsTheVarianceOrTheStd) {
  const auto a = truncated_normal_from_json(
      {{"mean", 0.75}, {"variance", 0.5}, {"lower", -1.5}, {"upper", 1.5}}, "interventions.j[0]");
  EXPECT_EQ(a.sigma(), std::sqrt(0.5));
  EXPECT_EQ(a.mu(), 0.75);
  const auto b = truncated_normal_from_json(
      {{"mean", 0.75}, {"std", 0.5}, {"lower", -1.5}, {"upper", 1.5}}, "interventions.j[0]");
  EXPECT_EQ(b.sigma(), 0.5);
  const auto message = [](const nlohmann::json& j) {
    try {
      truncated_normal_from_json(j, "interventions.j[1]");
    } catch (const std::invalid_argument& e) {
      return std::string(e.what());
    }
    return std::string();
  };
  EXPECT_EQ(message({{"mean", 0}, {"variance", 1}, {"std", 1}, {"lower", 0}, {"upper", 1}}),
            "interventions.j[1]: gives both variance and std; expected exactly one");
  EXPECT_EQ(message({{"mean", 0}, {"lower", 0}, {"upper", 1}}),
            "interventions.j[1]: gives neither variance nor std; expected exactly one");
  EXPECT_NE(message({{"mean", 0}, {"variance", -1}, {"lower", 0}, {"upper", 1}})
                .find("interventions.j[1].variance: expected a finite number > 0, got -1"),
            std::string::npos);
}

TEST(BayesAccuracy, RefusesDegenerateDistributions) {
  // no such distribution (ropes_core's TruncatedNormal refuses it, naming the values)
  EXPECT_THROW(bayes_accuracy({0, 0, -1, 1}, {0, 1, -1, 1}), std::invalid_argument);
  EXPECT_THROW(bayes_accuracy({0, 1, 1, 1}, {0, 1, -1, 1}), std::invalid_argument);
  EXPECT_NE(message_of([] {
              truncated_normal_from_json({{"mean", 0}, {"std", 0}, {"lower", 0}, {"upper", 1}},
                                         "interventions.j[0]");
            }).find("interventions.j[0]: TruncatedNormal(mu=0, sigma=0"),
            std::string::npos);
  try {
    truncated_normal_from_json({{"mean", 0}, {"std", 1}, {"lower", 0}}, "interventions.j[0]");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("interventions.j[0].upper: missing"), std::string::npos)
        << e.what();
  }
}
