// screen_run on a hand-made run: a code that holds one joint linearly, another only through a
// nonlinear map, and nothing of a third.
#include "ropes_eval/screening.hpp"

#include <gtest/gtest.h>

#include <ropes_core/dataset.hpp>
#include <ropes_core/npy.hpp>
#include <ropes_core/philox.hpp>
#include <ropes_crl/experiment_config.hpp>

#include <nlohmann/json.hpp>

#include <unistd.h>

#include <cmath>
#include <cstring>
#include <filesystem>
#include <fstream>
#include <iostream>
#include <string>
#include <vector>

namespace fs = std::filesystem;
namespace core = ropes::core;
using ropes::eval::screen_run;
using ropes::eval::Screening;
using ropes::eval::ScreeningOptions;

namespace {

// a whole config, as a run.json holds one (RunDirectory reads it), named for this test
nlohmann::json hand_made_config() {
  nlohmann::json c = ropes::crl::load_experiment_config("1c-tiny").to_json();
  c["name"] = "hand-made";
  return c;
}

constexpr std::int64_t kAnchors = 300, kPerAnchor = 3, kRows = kAnchors * kPerAnchor;

// RUN/ and DATA/ under a fresh directory: DATA holds angles f32 [n, 3] (joints a, b, c, each
// uniform in [-1.5, 1.5], drawn per row) and anchor i64 [n]; RUN/codes.npy is f32 [n, 1, 2, 2]:
// a, b^3, and two elements of noise, so the code holds a linearly, b only through a curved
// (invertible) map, and c not at all. run.json records LDRs for a and b, none for c.
fs::path make_run(const std::string& name) {
  const fs::path dir =
      fs::temp_directory_path() / ("ropes_screening_" + name + "_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  fs::create_directories(dir / "run");
  core::NpyArray angles{core::DType::kF32, {kRows, 3}, std::vector<std::uint8_t>(kRows * 3 * 4)};
  core::NpyArray anchor{core::DType::kI64, {kRows}, std::vector<std::uint8_t>(kRows * 8)};
  core::NpyArray codes{
      core::DType::kF32, {kRows, 1, 2, 2}, std::vector<std::uint8_t>(kRows * 4 * 4)};
  for (std::int64_t r = 0; r < kRows; ++r) {
    core::PhiloxStream rng(/*seed=*/11, /*stream=*/static_cast<std::uint64_t>(r));
    float q[3], y[4];
    for (float& v : q)
      v = static_cast<float>(3 * rng.uniform_double() - 1.5);
    y[0] = q[0];
    y[1] = q[1] * q[1] * q[1];
    y[2] = static_cast<float>(rng.uniform_double());
    y[3] = static_cast<float>(rng.uniform_double());
    const std::int64_t a = r / kPerAnchor;
    std::memcpy(&angles.data[static_cast<std::size_t>(r * 12)], q, 12);
    std::memcpy(&anchor.data[static_cast<std::size_t>(r * 8)], &a, 8);
    std::memcpy(&codes.data[static_cast<std::size_t>(r * 16)], y, 16);
  }
  const std::vector<core::ColumnSpec> columns = {{"angles", core::DType::kF32, {3}},
                                                 {"anchor", core::DType::kI64, {}}};
  core::write_dataset_shard(dir / "data", 0, columns, {angles, anchor});
  core::write_dataset_manifest(dir / "data", columns, 1,
                               R"({"joint_names": ["a", "b", "c"], "sim_dataset_version": 3})");
  core::write_npy(dir / "run" / "codes.npy", codes);
  const nlohmann::json run = {{"format", "ropes-run"},
                              {"format_version", 1},
                              {"joints", {"a", "b", "c"}},
                              {"data_dir", (dir / "data").string()},
                              {"dataset", "made-by-hand"},
                              {"seed", 0},
                              {"config", hand_made_config()},
                              {"ldr",
                               {{"a", {{"held_out_accuracy", 0.91}, {"bayes_accuracy", 0.93}}},
                                {"b", {{"held_out_accuracy", 0.52}, {"bayes_accuracy", 0.93}}}}}};
  std::ofstream(dir / "run" / "run.json") << run.dump(2);
  return dir;
}

}  // namespace

// The linear probe explains a (R^2 near 1), b only in part (for b uniform on a symmetric
// interval, corr(b, b^3)^2 = (1/5)^2 / (1/3 * 1/7) = 0.84) and c not at all; the MLP also
// inverts the cube (R^2 above the linear probe's) and finds nothing of c. The LDR columns are
// run.json's, NaN where no LDR trained. The witness of the R^2: the code is built from the
// angles, so what each probe can explain is known by construction.
TEST(Screening, ExplainsWhatTheCodeHoldsAndNothingElse) {
  const fs::path dir = make_run("holds");
  ScreeningOptions o;
  o.probe_steps = 1500;
  const Screening s = screen_run(dir / "run", o);
  std::cout << s.table();
  ASSERT_EQ(s.joints, (std::vector<std::string>{"a", "b", "c"}));
  EXPECT_EQ(s.test_anchors, 60);  // 20 % of 300
  EXPECT_EQ(s.train_anchors, 240);
  EXPECT_EQ(s.test_rows, 60 * kPerAnchor);
  EXPECT_EQ(s.train_rows + s.test_rows, kRows);
  ASSERT_EQ(s.probe_linear_r2.size(), 3u);
  ASSERT_EQ(s.probe_mlp_r2.size(), 3u);
  EXPECT_GT(s.probe_linear_r2[0], 0.999);
  EXPECT_NEAR(s.probe_linear_r2[1], 0.84, 0.05);
  EXPECT_LT(s.probe_linear_r2[2], 0.1);
  EXPECT_GT(s.probe_mlp_r2[0], 0.95);
  EXPECT_GT(s.probe_mlp_r2[1], s.probe_linear_r2[1] + 0.05);  // the curve the line misses
  EXPECT_LT(s.probe_mlp_r2[2], 0.2);
  // R^2 = 1 - MSE / variance, the variance of a uniform on [-1.5, 1.5] being 0.75
  for (std::size_t k = 0; k < 3; ++k) {
    EXPECT_NEAR(s.probe_linear_r2[k], 1 - s.probe_linear_mse[k] / s.angle_variance[k], 1e-12);
    EXPECT_NEAR(s.angle_variance[k], 0.75, 0.15);
  }
  EXPECT_EQ(s.ldr_accuracy[0], 0.91);
  EXPECT_EQ(s.bayes_accuracy[1], 0.93);
  EXPECT_TRUE(std::isnan(s.ldr_accuracy[2]));
  const nlohmann::json j = s.to_json();
  EXPECT_EQ(j["format"], "ropes-eval-screen");
  EXPECT_TRUE(j["ldr_accuracy"][2].is_null());
  EXPECT_EQ(j["split"]["test_anchors"], 60);
  EXPECT_NE(s.table().find("| a | "), std::string::npos) << s.table();
  // the same seed, the same numbers; another seed holds out other anchors
  const Screening again = screen_run(dir / "run", o);
  EXPECT_EQ(again.probe_mlp_mse, s.probe_mlp_mse);
  o.seed = 1;
  o.probe_steps = 0;
  EXPECT_NE(screen_run(dir / "run", o).probe_linear_mse, s.probe_linear_mse);
  fs::remove_all(dir);
}

TEST(Screening, RefusesARunWithoutCodesAndBadOptions) {
  const fs::path dir = make_run("refuse");
  ScreeningOptions o;
  o.probe_steps = 0;
  EXPECT_TRUE(screen_run(dir / "run", o).probe_mlp_r2.empty());
  o.test_fraction = 1.0;
  EXPECT_THROW(screen_run(dir / "run", o), std::invalid_argument);
  o.test_fraction = 0.2;
  o.probe_steps = -1;
  EXPECT_THROW(screen_run(dir / "run", o), std::invalid_argument);
  o.probe_steps = 0;
  // a training set of the old reading of the paper's TN(mean, x)
  {
    nlohmann::json m = nlohmann::json::parse(std::ifstream(dir / "data" / "manifest.json"));
    m["metadata"]["sim_dataset_version"] = 2;
    std::ofstream(dir / "data" / "manifest.json") << m.dump();
    try {
      screen_run(dir / "run", o);
      ADD_FAILURE() << "a run of a sim_dataset_version 2 training set was screened";
    } catch (const core::FileFormatError& e) {
      EXPECT_NE(std::string(e.what()).find("sim_dataset_version 2, made when ropes-generate"),
                std::string::npos)
          << e.what();
    }
    m["metadata"]["sim_dataset_version"] = 3;
    std::ofstream(dir / "data" / "manifest.json") << m.dump();
  }
  fs::remove(dir / "run" / "codes.npy");
  try {
    screen_run(dir / "run", o);
    ADD_FAILURE() << "a run without codes.npy was screened";
  } catch (const core::FileFormatError& e) {
    EXPECT_NE(std::string(e.what()).find("codes.npy is missing: AE1 has not finished"),
              std::string::npos)
        << e.what();
  }
  std::ofstream(dir / "run" / "run.json") << "[1, 2]";
  EXPECT_THROW(screen_run(dir / "run", o), core::FileFormatError);
  fs::remove_all(dir);
}
