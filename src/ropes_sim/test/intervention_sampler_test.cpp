#include "ropes_sim/intervention_sampler.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

namespace ropes::sim {
namespace {

const std::filesystem::path kDir = ROPES_SIM_DISTRIBUTIONS_DIR;

// index of panda_joint<number> in the configs' joint list
int joint(const InterventionSampler&, int number) {
  return number - 1;
}

// Witness: the paper's tables, read off by hand (appendix tab:singleTrunc,
// tab:twoCamera_trunc, tab:ood_distributions, tab:noise_models and the SEM equations).
TEST(InterventionSamplerGolden, ConfigsCarryThePapersNumbers) {
  const auto one = InterventionSampler::load(kDir / "1c_independent.json");
  EXPECT_EQ(one.regime_names().size(), 7u);  // 1 + 2 x joints 2, 4, 6
  EXPECT_EQ(one.regime_names()[5], "do(panda_joint6)=1");
  ASSERT_EQ(one.regimes().size(), 7u);
  EXPECT_EQ(one.regimes()[0].joint, -1);
  EXPECT_EQ(one.regimes()[0].intervention, 0);
  EXPECT_EQ(one.regimes()[5].joint, 5);  // panda_joint6
  EXPECT_EQ(one.regimes()[5].intervention, 1);
  EXPECT_EQ(one.regimes()[2].joint, 1);  // do(panda_joint2)=2
  EXPECT_EQ(one.regimes()[2].intervention, 2);
  const TruncatedNormal& j6 = one.interventions(joint(one, 6))[0];
  EXPECT_EQ(j6.mu(), 2.25);
  EXPECT_EQ(j6.sigma(), std::sqrt(0.5));  // the table's 0.5 is a variance (paper line 472)
  EXPECT_EQ(j6.lower(), 0.0);
  EXPECT_EQ(j6.upper(), 3.0);
  EXPECT_EQ(one.observational(joint(one, 2))->sigma(), 1.0);

  const auto two = InterventionSampler::load(kDir / "2c_independent.json");
  EXPECT_EQ(two.regime_names().size(), 13u);  // 1 + 2 x joints 1..6
  EXPECT_EQ(two.interventions(joint(two, 4))[1].mu(), -0.9);
  EXPECT_EQ(two.observational(joint(two, 1))->mu(), 1.2);
  EXPECT_EQ(two.observational(joint(two, 2))->sigma(), std::sqrt(0.4));

  const auto ood = InterventionSampler::load(kDir / "2c_ood.json");
  EXPECT_EQ(ood.observational(joint(ood, 4))->mu(), 0.8);
  EXPECT_EQ(ood.observational(joint(ood, 6))->mu(), 0.5);
  EXPECT_EQ(ood.interventions(joint(ood, 6))[0].mu(), 2.4);

  const auto causal = InterventionSampler::load(kDir / "2c_causal.json");
  EXPECT_EQ(causal.sem_weight(joint(causal, 3), joint(causal, 2)), 0.88);
  EXPECT_EQ(causal.sem_weight(joint(causal, 6), joint(causal, 3)), 0.37);
  EXPECT_FALSE(causal.observational(joint(causal, 3)).has_value());  // not a root
  ASSERT_TRUE(causal.sem_noise().has_value());
  EXPECT_EQ(causal.sem_noise()->sigma(), std::sqrt(0.1));  // TN_[0,1](0, 0.1), a variance
}

// The first two samples (observational, first intervention) of anchor 0 under seed 0, per
// config: a regression pin produced by the code (the sampling itself is checked against
// closed-form moments and numeric integration in truncated_normal_test.cpp). Independent
// checks here: held joints equal the config, the intervention changes only its joint (and,
// in the SEM, joint 6 = its parents' weighted sum + the anchor's noise, recomputed here).
// Regenerate by printing sample_anchor(0, 0)[0..1] with %.17g. Witness of the variance
// reading (sigma = sqrt(x)): test/witness_variance_reading.py checks with scipy that each
// independent pin and its sim_dataset_version 2 value (x read as sigma) are the quantiles of
// one and the same uniform.
TEST(InterventionSamplerGolden, FirstSamplesOfEachConfigForSeedZero) {
  struct Case {
    const char* name;
    std::vector<std::vector<double>> first;
  };
  const Case cases[] = {
      {"1c_independent",
       {{0, -0.22102799491644551, 0, 0.5365714433627139, 0, 2.8354960536329941, 0.79},
        {0, -0.30024801591874711, 0, 0.5365714433627139, 0, 2.8354960536329941, 0.79}}},
      {"2c_independent",
       {{1.0650618945085879, 0.39052542784303274, 1.1369010957542958, 0.31449487516728047,
         -1.2090579409417079, 0.83714466671914978, 0.79},
        {2.4121950060356538, 0.39052542784303274, 1.1369010957542958, 0.31449487516728047,
         -1.2090579409417079, 0.83714466671914978, 0.79}}},
      {"2c_ood",
       {{1.0650618945085879, 0.39052542784303274, 1.1369010957542958, 0.96162925598204008,
         -1.2090579409417079, 0.21352861804018808, 0.79},
        {2.4121950060356538, 0.39052542784303274, 1.1369010957542958, 0.96162925598204008,
         -1.2090579409417079, 0.21352861804018808, 0.79}}},
      {"2c_causal",
       {{1.7753588878268367, 1.0037721081031095, 0.89101659106154529, 0.54932838103939408,
         0.49989482372384519, 1.7212974969726795, 0.79},
        {2.7708564870092913, 1.0037721081031095, 0.89101659106154529, 0.54932838103939408,
         0.49989482372384519, 1.9602169207764686, 0.79}}},
  };

  for (const Case& c : cases) {
    const auto s = InterventionSampler::load(kDir / (std::string(c.name) + ".json"));
    const auto got = s.sample_anchor(0, 0);
    for (std::size_t r = 0; r < 2; ++r)
      for (std::size_t j = 0; j < 7; ++j)
        EXPECT_EQ(got[r][j], c.first[r][j]) << c.name << " regime " << r << " joint " << j + 1;
  }
  // the SEM witness: do(joint1) moves joint 6 by w(6 <- 1) times the change of joint 1
  const auto sem = InterventionSampler::load(kDir / "2c_causal.json");
  const double w61 = sem.sem_weight(joint(sem, 6), joint(sem, 1));
  if (w61 != 0.0) {
    const Case& c = cases[3];
    EXPECT_NEAR(c.first[1][5] - c.first[0][5], w61 * (c.first[1][0] - c.first[0][0]), 1e-12);
  }
}

TEST(InterventionSampler, IndependentInterventionsChangeOneJointAndHoldTheRest) {
  const auto s = InterventionSampler::load(kDir / "1c_independent.json");
  const auto samples = s.sample_anchor(/*seed=*/3, /*anchor=*/41);
  ASSERT_EQ(samples.size(), 7u);
  const auto& base = samples[0];
  EXPECT_EQ(base[0], 0.0);   // held
  EXPECT_EQ(base[6], 0.79);  // held
  for (std::size_t r = 1; r < samples.size(); ++r) {
    const int changed = s.intervened_joints()[(r - 1) / 2];
    for (int j = 0; j < 7; ++j) {
      if (j != changed) {
        EXPECT_EQ(samples[r][static_cast<std::size_t>(j)], base[static_cast<std::size_t>(j)]);
      }
    }
  }
  // an anchor's samples depend on (seed, anchor) only
  EXPECT_EQ(s.sample_anchor(3, 41), samples);
  EXPECT_NE(s.sample_anchor(3, 42), samples);
}

TEST(InterventionSampler, TheCausalModelRecomputesDescendantsWithTheSameNoise) {
  const auto s = InterventionSampler::load(kDir / "2c_causal.json");
  const auto samples = s.sample_anchor(5, 9);
  const auto& base = samples[0];
  // regime 3 = do(panda_joint2)=1: J3 = 0.88 J2 + e3 with e3 unchanged, J5 follows J3, J6 all
  const auto& do2 = samples[3];
  EXPECT_NEAR(do2[2] - 0.88 * do2[1], base[2] - 0.88 * base[1], 1e-12);
  EXPECT_NEAR(do2[4] - 0.26 * do2[2], base[4] - 0.26 * base[2], 1e-12);
  EXPECT_NEAR(do2[5] - (0.24 * do2[0] + 0.31 * do2[1] + 0.37 * do2[2] + 0.15 * do2[4]),
              base[5] - (0.24 * base[0] + 0.31 * base[1] + 0.37 * base[2] + 0.15 * base[4]), 1e-12);
  EXPECT_EQ(do2[0], base[0]);  // not a descendant
  EXPECT_EQ(do2[3], base[3]);
  // do(panda_joint4): J4 has no children
  const auto& do4 = samples[7];
  for (int j : {0, 1, 2, 4, 5})
    EXPECT_EQ(do4[static_cast<std::size_t>(j)], base[static_cast<std::size_t>(j)]);
}

// The paper's TN_[-1.5,1.5](0, 0.4) read as a variance, as the paper defines it: the angles
// of the 2C observational joints have variance 0.35372 (scipy.stats.truncnorm(-1.5/s, 1.5/s,
// scale=s).var() with s = sqrt(0.4), Debian's python3-scipy 1.10), which is what the paper's
// own 2C row implies (MSE / (1 - MCC^2) = 0.35-0.37). Read as a standard deviation they would
// have variance 0.15958.
TEST(InterventionSampler, TwoCameraAnglesHaveThePapersVariance) {
  const auto s = InterventionSampler::load(kDir / "2c_independent.json");
  const int n = 20000;
  double sum = 0, sum2 = 0;
  for (int a = 0; a < n; ++a) {
    const double x = s.sample_anchor(2, static_cast<std::uint64_t>(a))[0][1];  // joint 2
    sum += x;
    sum2 += x * x;
  }
  const double mean = sum / n, variance = sum2 / n - mean * mean;
  EXPECT_NEAR(s.observational(joint(s, 2))->variance(), 0.3537228480016075, 1e-9);
  // the sample variance's standard error is about variance * sqrt(2 / n) = 0.0035
  EXPECT_NEAR(variance, 0.3537228480016075, 0.015);
}

TEST(InterventionSampler, ObservationalDrawsHaveTheTableMoments) {
  const auto s = InterventionSampler::load(kDir / "2c_independent.json");
  const TruncatedNormal& j6 = *s.observational(joint(s, 6));
  const int n = 20000;
  double sum = 0;
  for (int a = 0; a < n; ++a)
    sum += s.sample_anchor(1, static_cast<std::uint64_t>(a))[0][5];
  EXPECT_NEAR(sum / n, j6.mean(), 5 * std::sqrt(j6.variance() / n));
}

std::string load_error(const std::string& json) {
  const auto path = std::filesystem::temp_directory_path() / "ropes_sampler_test.json";
  std::ofstream(path) << json;
  try {
    InterventionSampler::load(path);
  } catch (const ConfigError& e) {
    std::filesystem::remove(path);
    return e.what();
  }
  std::filesystem::remove(path);
  return "";
}

TEST(InterventionSampler, RefusesBadConfigsNamingTheFieldAndValue) {
  const std::string head = R"({"name": "t", "joints": ["a", "b"], "held": {"b": 0},)";
  EXPECT_EQ(
      load_error(
          head +
          R"("observational": {"a": {"mean": 0, "std": 1, "lower": -1, "upper": 1}}, "interventions": {}})"),
      "");
  EXPECT_NE(
      load_error(
          head +
          R"("observational": {"c": {"mean": 0, "std": 1, "lower": -1, "upper": 1}}, "interventions": {}})")
          .find("observational names joint 'c', which is not in joints"),
      std::string::npos);
  EXPECT_NE(
      load_error(
          head +
          R"("observational": {"a": {"mean": 0, "std": 1, "lower": 1, "upper": 1}}, "interventions": {}})")
          .find("observational.a: TruncatedNormal(mu=0, sigma=1, lower=1, upper=1)"),
      std::string::npos);
  EXPECT_NE(
      load_error(
          head +
          R"("observational": {"a": {"mean": 0, "std": -2, "lower": -1, "upper": 1}}, "interventions": {}})")
          .find("sigma=-2"),
      std::string::npos);
  // the spread: `variance` (the paper's parameter) or `std`, exactly one
  EXPECT_EQ(
      load_error(
          head +
          R"("observational": {"a": {"mean": 0, "variance": 1, "lower": -1, "upper": 1}}, "interventions": {}})"),
      "");
  EXPECT_NE(
      load_error(
          head +
          R"("observational": {"a": {"mean": 0, "lower": -1, "upper": 1}}, "interventions": {}})")
          .find("observational.a gives neither 'variance' nor 'std'; expected exactly one"),
      std::string::npos);
  EXPECT_NE(
      load_error(
          head +
          R"("observational": {"a": {"mean": 0, "variance": 1, "std": 1, "lower": -1, "upper": 1}}, "interventions": {}})")
          .find("observational.a gives both 'variance' and 'std'; expected exactly one"),
      std::string::npos);
  EXPECT_NE(
      load_error(
          head +
          R"("observational": {"a": {"mean": 0, "variance": -0.5, "lower": -1, "upper": 1}}, "interventions": {}})")
          .find("observational.a.variance is -0.5; expected a finite number > 0"),
      std::string::npos);
  EXPECT_NE(
      load_error(
          head +
          R"("observational": {"a": {"mean": 0, "variance": "big", "lower": -1, "upper": 1}}, "interventions": {}})")
          .find("observational.a.variance is \"big\"; expected a number"),
      std::string::npos);
  EXPECT_NE(load_error(head + R"("observational": {}, "interventions": {}})")
                .find("joint 'a' is neither held, observational nor a child in the sem"),
            std::string::npos);
  EXPECT_NE(
      load_error(
          head +
          R"("observational": {"a": {"mean": 0, "std": 1, "lower": -1, "upper": 1}}, "interventions": {"a": []}})")
          .find("interventions.a must list two distributions"),
      std::string::npos);
  EXPECT_NE(load_error("{not json").find("not JSON"), std::string::npos);
  try {
    InterventionSampler::load("/nonexistent/d.json");
    ADD_FAILURE() << "no exception";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("/nonexistent/d.json: cannot open"), std::string::npos);
  }
}

}  // namespace
}  // namespace ropes::sim
