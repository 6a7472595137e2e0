// RunDirectory: the one reader of run.json. What the trainer records comes back typed; what is
// not a run is refused by field, as core::FileFormatError naming run.json.
#include "ropes_crl/run_directory.hpp"

#include <gtest/gtest.h>

#include <cmath>
#include <filesystem>
#include <fstream>
#include <string>

#include "ropes_core/file_format_error.hpp"
#include "ropes_core/scratch_dir.hpp"

namespace ropes::crl {
namespace {

namespace fs = std::filesystem;

class RunDirectoryTest : public ::testing::Test {
 protected:
  void SetUp() override {
    config_ = load_experiment_config(std::string(ROPES_CRL_SOURCE_CONFIGS) + "/1c-tiny.json");
    // the keys ropes-train writes (trainer.cpp, open_run and train)
    run_ = {{"format", "ropes-run"},
            {"format_version", 1},
            {"config", config_.to_json()},
            {"dataset", "abc123"},
            {"seed", 7},
            {"threads", 2},
            {"data_dir", "/data/tiny-1c"},
            {"joints", config_.joints},
            {"provenance", {{"isa_level", "x86-64-v4"}}},
            {"stages", nlohmann::json::object()}};
  }
  void write(const std::string& text) { std::ofstream(dir_ / "run.json") << text; }
  std::string error() {
    try {
      RunDirectory::open(dir_);
    } catch (const core::FileFormatError& e) {
      return e.what();
    }
    return "(opened)";
  }
  core::ScratchDir scratch_{"ropes_run_directory"};
  const fs::path dir_ = scratch_.path();
  ExperimentConfig config_;
  nlohmann::json run_;
};

TEST_F(RunDirectoryTest, ReadsWhatTheTrainerRecordsAtEachStage) {
  write(run_.dump());
  const RunDirectory before = RunDirectory::open(dir_);
  EXPECT_EQ(before.config().name, "1c-tiny");
  EXPECT_EQ(before.joints(), config_.joints);
  EXPECT_EQ(before.data_dir(), "/data/tiny-1c");
  EXPECT_EQ(before.dataset_id(), "abc123");
  EXPECT_EQ(before.seed(), 7u);
  EXPECT_FALSE(before.complete());
  EXPECT_EQ(before.provenance()["isa_level"], "x86-64-v4");
  EXPECT_FALSE(before.ldr(config_.joints[0]).has_value());
  EXPECT_TRUE(before.sparsity_matrices().empty());
  EXPECT_EQ(before.codes_file(), dir_ / "codes.npy");

  run_["ldr"][config_.joints[0]] = {
      {"held_out_loss", 0.4}, {"held_out_accuracy", 0.8}, {"bayes_accuracy", 0.83}, {"epochs", 12}};
  run_["sparsity_matrix"]["joint2"] = {{1.0, 0.0}, {0.5, nullptr}};
  run_["complete"] = true;
  write(run_.dump());
  const RunDirectory after = RunDirectory::open(dir_);
  EXPECT_TRUE(after.complete());
  const auto l = after.ldr(config_.joints[0]);
  ASSERT_TRUE(l.has_value());
  EXPECT_DOUBLE_EQ(l->held_out_accuracy, 0.8);
  EXPECT_DOUBLE_EQ(l->bayes_accuracy, 0.83);
  EXPECT_EQ(l->epochs, 12);
  ASSERT_EQ(after.sparsity_matrices().size(), 1u);
  EXPECT_EQ(after.sparsity_matrices()[0].model, "joint2");
  EXPECT_DOUBLE_EQ(after.sparsity_matrices()[0].rows[1][0], 0.5);
  EXPECT_TRUE(std::isnan(after.sparsity_matrices()[0].rows[1][1]));
}

TEST_F(RunDirectoryTest, WhatIsNotARunIsRefusedNamingRunJsonAndTheField) {
  const std::string file = (dir_ / "run.json").string();
  EXPECT_EQ(error(),
            file + ": missing; is '" + dir_.string() + "' a run directory of ropes-train?");
  write("[1, 2]");
  EXPECT_EQ(error(), file + ": holds a JSON array; expected a ropes run (a JSON object)");
  write(R"({"format": "ropes-dataset"})");
  EXPECT_EQ(error(), file + ": not a ropes run (format \"ropes-dataset\", expected \"ropes-run\")");
  nlohmann::json r = run_;
  r["joints"] = {"joint2", 4};
  write(r.dump());
  EXPECT_EQ(error(), file + ": joints holds 4; expected joint names");
  r = run_;
  r["seed"] = -1;
  write(r.dump());
  EXPECT_EQ(error(), file + ": seed is -1; expected a non-negative integer");
  r = run_;
  r.erase("data_dir");
  write(r.dump());
  EXPECT_EQ(error(), file + ": data_dir is missing; expected the training set's directory");
  r = run_;
  r["config"]["ae1"]["widths"] = "wide";
  write(r.dump());
  EXPECT_NE(error().find(file), std::string::npos) << error();
  EXPECT_NE(error().find("widths"), std::string::npos) << error();
  r = run_;
  r["provenance"] = "x86";
  write(r.dump());
  EXPECT_EQ(error(), file + ": provenance is \"x86\"; expected an object");
  r = run_;
  r["ldr"] = {1, 2};
  write(r.dump());
  EXPECT_EQ(error(), file + ": ldr is a JSON array; expected an object of joints");
  r = run_;
  r["sparsity_matrix"] = {{"joint2", 3}};
  write(r.dump());
  EXPECT_EQ(error(), file + ": sparsity_matrix.joint2 is 3; expected an array of rows");
  write("{\"format\": ");
  EXPECT_EQ(error().rfind(file + ": is not JSON", 0), 0u) << error();
}

}  // namespace
}  // namespace ropes::crl
