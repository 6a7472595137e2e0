#include "ropes_sim/trajectory.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>

namespace ropes::sim {
namespace {

const std::filesystem::path kConfig =
    std::filesystem::path(ROPES_SIM_DISTRIBUTIONS_DIR) / "2c_independent.json";

TEST(Trajectory, PassesThroughTheTargetsWithZeroVelocityThere) {
  const auto sampler = InterventionSampler::load(kConfig);
  Trajectory trajectory(sampler, 4, /*segment_seconds=*/2.0, /*rate_hz=*/50.0);
  // at segment boundaries the arm is at the anchors' observational configurations
  EXPECT_EQ(trajectory.at(0.0), sampler.sample_anchor(4, 0)[0]);
  const std::vector<double> at4 = trajectory.at(4.0), target2 = sampler.sample_anchor(4, 2)[0];
  for (std::size_t j = 0; j < at4.size(); ++j)
    EXPECT_NEAR(at4[j], target2[j], 1e-12);
  // central differences: velocity ~0 at a target, and continuous across it
  const double h = 1e-4;
  const auto before = trajectory.at(2.0 - h), after = trajectory.at(2.0 + h);
  for (std::size_t j = 0; j < before.size(); ++j)
    EXPECT_NEAR((after[j] - before[j]) / (2 * h), 0.0, 1e-6);
  // mid-segment the motion is halfway (the quintic blend is 1/2 at s = 1/2)
  const auto mid = trajectory.at(1.0), a = trajectory.at(0.0), b = trajectory.at(2.0);
  for (std::size_t j = 0; j < mid.size(); ++j)
    EXPECT_NEAR(mid[j], 0.5 * (a[j] + b[j]), 1e-12);
}

TEST(Trajectory, NextStepsAtTheRateAndIsDeterministic) {
  const auto sampler = InterventionSampler::load(kConfig);
  Trajectory one(sampler, 9, 1.0, 30.0), two(sampler, 9, 1.0, 30.0);
  for (int i = 0; i < 100; ++i) {
    const Trajectory::Point p = one.next();
    EXPECT_NEAR(p.time, i / 30.0, 1e-12);
    EXPECT_EQ(p.q, two.next().q);
  }
  EXPECT_THROW(Trajectory(sampler, 1, 0.0, 30.0), std::invalid_argument);
  EXPECT_THROW(Trajectory(sampler, 1, 1.0, -5.0), std::invalid_argument);
  EXPECT_THROW(one.at(-1.0), std::invalid_argument);
}

}  // namespace
}  // namespace ropes::sim
