#pragma once
// The fixture of the trainer's stage tests (trainer_ae1_test.cpp, trainer_ldr_test.cpp,
// trainer_ae2_test.cpp): a scratch directory with the synthetic two-joint dataset at the tiny
// preset's size, 1c-tiny pointed at it with a few steps a stage, and runs of it.
#include <ropes_crl/run_directory.hpp>
#include <ropes_crl/trainer.hpp>
#include <ropes_nn/parallel.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <filesystem>
#include <fstream>
#include <string>
#include <vector>

#include "synthetic_run.hpp"

namespace ropes::crl::test_support {

class TrainerStage : public ::testing::Test {
 protected:
  void SetUp() override {
    const auto* info = ::testing::UnitTest::GetInstance()->current_test_info();
    dir_ = std::filesystem::temp_directory_path() /
           ("ropes_crl_" + std::string(info->test_suite_name()) + "_" + info->name() + "_" +
            std::to_string(::getpid()));
    std::filesystem::remove_all(dir_);
    // 6 steps of AE1 and of each AE2, 2 LDR epochs, a checkpoint every 2 steps
    config_ = two_joint_config("1c-tiny", 6, 2, 2);
    write_two_bar_dataset(data(), config_.cameras, config_.image_size);
    options_.threads = 2;
  }
  void TearDown() override {
    nn::set_num_threads(2);
    std::filesystem::remove_all(dir_);
  }
  std::filesystem::path data() const { return dir_ / "data"; }
  // trains (or resumes) the run `name` up to `last_stage`
  std::filesystem::path train_to(const std::string& name, int last_stage,
                                 TrainOptions options) const {
    options.last_stage = last_stage;
    train(config_, data(), dir_ / name, options);
    return dir_ / name;
  }
  // the records of metrics.jsonl of `stage`
  std::vector<nlohmann::json> records(const std::filesystem::path& run,
                                      const std::string& stage) const {
    std::vector<nlohmann::json> out;
    std::ifstream in(run / "metrics.jsonl");
    std::string line;
    while (std::getline(in, line)) {
      const nlohmann::json r = nlohmann::json::parse(line);
      if (r.value("stage", "") == stage)
        out.push_back(r);
    }
    return out;
  }

  std::filesystem::path dir_;
  ExperimentConfig config_;
  TrainOptions options_;
};

}  // namespace ropes::crl::test_support
