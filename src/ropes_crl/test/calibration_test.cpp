// Calibration: the one calibration type, its file, the run it records, and where a run's
// latest evaluation's calibration is found (never inside the run directory).
#include "ropes_crl/calibration.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "ropes_core/file_format_error.hpp"
#include "ropes_core/scratch_dir.hpp"
#include "ropes_crl/run_directory.hpp"

namespace ropes::crl {
namespace {

namespace fs = std::filesystem;

class CalibrationTest : public ::testing::Test {
 protected:
  void SetUp() override {
    fs::create_directories(run_dir_);
    write_run(7);
  }
  // a run.json of the keys ropes-train writes (as in run_directory_test.cpp)
  void write_run(std::uint64_t seed) {
    const ExperimentConfig config =
        load_experiment_config(std::string(ROPES_CRL_SOURCE_CONFIGS) + "/1c-tiny.json");
    const nlohmann::json run = {{"format", "ropes-run"},        {"config", config.to_json()},
                                {"dataset", "abc123def456789"}, {"seed", seed},
                                {"data_dir", "/data/tiny-1c"},  {"joints", config.joints}};
    std::ofstream(run_dir_ / "run.json") << run.dump();
  }
  Calibration fitted(const RunDirectory& run) const {
    Calibration c;
    c.joints = run.joints();
    for (std::size_t k = 0; k < c.joints.size(); ++k) {
      c.scale.push_back(1.5 + static_cast<double>(k));
      c.offset.push_back(-0.25 * static_cast<double>(k));
    }
    c.run = RunIdentity::of(run);
    return c;
  }
  core::ScratchDir scratch_{"ropes_calibration"};
  const fs::path dir_ = scratch_.path();
  const fs::path run_dir_ = dir_ / "runs" / "a";
};

TEST_F(CalibrationTest, RoundTripsThroughItsFileWithTheRunItWasFittedFor) {
  const RunDirectory run = RunDirectory::open(run_dir_);
  const Calibration c = fitted(run);
  ASSERT_EQ(c.joints.size(), 3u);
  EXPECT_EQ(c.joint(1).scale, 2.5);
  EXPECT_EQ(c.joint(2).offset, -0.5);
  EXPECT_THROW(c.joint(3), std::out_of_range);
  const fs::path file = dir_ / "calibration.json";
  c.write(file);
  const Calibration back = Calibration::read(file);
  EXPECT_EQ(back.joints, c.joints);
  EXPECT_EQ(back.scale, c.scale);
  EXPECT_EQ(back.offset, c.offset);
  ASSERT_TRUE(back.run.has_value());
  EXPECT_EQ(*back.run, *c.run);
  EXPECT_EQ(back.run->config, "1c-tiny");
  EXPECT_EQ(back.run->seed, 7u);
  EXPECT_EQ(back.run->dataset, "abc123def456789");
  EXPECT_EQ(back.run->config_sha256.size(), 64u);
  EXPECT_EQ(back.to_json(), c.to_json());
  back.check_fits(run);
}

TEST_F(CalibrationTest, RefusesAFileByFieldAndARunItWasNotFittedFor) {
  const RunDirectory run = RunDirectory::open(run_dir_);
  nlohmann::json j = fitted(run).to_json();
  j["scale"] = {1.0};
  EXPECT_THROW(
      {
        try {
          Calibration::from_json(j);
        } catch (const std::invalid_argument& e) {
          EXPECT_STREQ(e.what(), "calibration.scale: expected 3 numbers, got a JSON array");
          throw;
        }
      },
      std::invalid_argument);
  j = fitted(run).to_json();
  j["run"]["seed"] = -1;
  std::ofstream(dir_ / "bad.json") << j.dump();
  try {
    Calibration::read(dir_ / "bad.json");
    ADD_FAILURE() << "read a negative seed";
  } catch (const core::FileFormatError& e) {
    EXPECT_EQ(std::string(e.what()),
              (dir_ / "bad.json").string() +
                  ": calibration.run.seed: expected a non-negative integer, got -1");
  }
  j = fitted(run).to_json();
  j["format"] = "ropes-run";
  EXPECT_THROW(Calibration::from_json(j), std::invalid_argument);

  // another seed is another run (DESIGN.md: a seed gives the bytes)
  Calibration other = fitted(run);
  other.run->seed = 8;
  try {
    other.check_fits(run);
    ADD_FAILURE() << "fitted another run";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("fitted for another run (config 1c-tiny"),
              std::string::npos)
        << e.what();
    EXPECT_NE(std::string(e.what()).find("seed 8"), std::string::npos) << e.what();
  }
  Calibration joints = fitted(run);
  joints.joints.back() = "panda_joint7";
  EXPECT_THROW(joints.check_fits(run), std::invalid_argument);
  // a file from before the run was recorded: any run of its joints
  Calibration old = fitted(run);
  old.run.reset();
  EXPECT_FALSE(old.to_json().contains("run"));
  old.check_fits(run);
}

TEST_F(CalibrationTest, TheEvaluationDirectoryIsBesideTheRun) {
  EXPECT_EQ(default_evaluation_dir("runs/a"), fs::path("runs/a-eval"));
  EXPECT_EQ(default_evaluation_dir("runs/a/"), fs::path("runs/a-eval"));
  EXPECT_EQ(default_evaluation_dir("runs/a/./"), fs::path("runs/a-eval"));
  EXPECT_EQ(default_evaluation_dir("/x/y"), fs::path("/x/y-eval"));
  EXPECT_EQ(default_evaluation_dir("a"), fs::path("a-eval"));
  const fs::path cwd = fs::current_path();
  EXPECT_EQ(default_evaluation_dir("."), cwd.parent_path() / (cwd.filename().string() + "-eval"));
  EXPECT_THROW(default_evaluation_dir("/"), std::invalid_argument);
}

TEST_F(CalibrationTest, TheLatestCalibrationIsTheNewestThatRecordsTheRun) {
  const RunDirectory run = RunDirectory::open(run_dir_);
  EXPECT_FALSE(latest_calibration(run).has_value());
  const fs::path eval = dir_ / "runs" / "a-eval";
  fs::create_directories(eval / "report");
  fitted(run).write(eval / "calibration.json");
  EXPECT_EQ(latest_calibration(run), eval / "calibration.json");
  // the suites' report, written later, wins
  fitted(run).write(eval / "report" / "calibration.json");
  const auto now = fs::last_write_time(eval / "calibration.json");
  fs::last_write_time(eval / "report" / "calibration.json", now + std::chrono::seconds(5));
  EXPECT_EQ(latest_calibration(run), eval / "report" / "calibration.json");
  // one of another run is passed over, and said so
  Calibration other = fitted(run);
  other.run->seed = 8;
  other.write(eval / "report" / "calibration.json");
  fs::last_write_time(eval / "report" / "calibration.json", now + std::chrono::seconds(10));
  std::vector<std::string> skipped;
  EXPECT_EQ(latest_calibration(run, &skipped), eval / "calibration.json");
  ASSERT_EQ(skipped.size(), 1u);
  EXPECT_NE(skipped[0].find((eval / "report" / "calibration.json").string() +
                            ": the calibration was fitted for another run"),
            std::string::npos)
      << skipped[0];
  // ropes-run's OUT/run: OUT/report, only where OUT holds ropes-run.json
  const fs::path out = dir_ / "out";
  fs::create_directories(out / "report");
  fs::copy(run_dir_, out / "run", fs::copy_options::recursive);
  const RunDirectory in_out = RunDirectory::open(out / "run");
  fitted(in_out).write(out / "report" / "calibration.json");
  EXPECT_FALSE(latest_calibration(in_out).has_value());
  std::ofstream(out / "ropes-run.json") << "{}";
  EXPECT_EQ(latest_calibration(in_out), out / "report" / "calibration.json");
  // nothing in the run directory counts
  fitted(run).write(run_dir_ / "calibration.json");
  EXPECT_EQ(calibration_candidates(run).size(), 2u);
}

}  // namespace
}  // namespace ropes::crl
