// The trainer's stage 3 at the tiny preset's size: an AE2 a joint and the lambda = 0
// baseline, the sparsity matrices in run.json and the run complete; and a run stopped inside
// the stage (the test hook throws after an AE2's checkpoint) that resumes to the bytes of a
// run never stopped.
#include <stdexcept>

#include "trainer_stage_fixture.hpp"

namespace ropes::crl::test_support {
namespace {

namespace fs = std::filesystem;

using TrainerAe2 = TrainerStage;

TEST_F(TrainerAe2, TrainsAnAe2AJointAndTheBaselineAndCompletesTheRun) {
  const fs::path run = train_to("run", 3, options_);
  const RunDirectory r = RunDirectory::open(run);
  EXPECT_TRUE(r.complete());
  for (const char* model : {"a", "b", "lambda0"}) {
    EXPECT_TRUE(fs::exists(run / (std::string("ae2.") + model + ".safetensors"))) << model;
    EXPECT_FALSE(fs::exists(run / (std::string("ae2.") + model + ".checkpoint.safetensors")));
  }
  // each AE2's sparsity matrix: a row per joint it is penalised on, a latent a column, the
  // means of |J_g^T v| (non-negative); the AE2 of joint a has a row
  bool have_a = false;
  for (const SparsityMatrix& m : r.sparsity_matrices()) {
    have_a = have_a || (m.model == "a" && !m.rows.empty());
    for (const std::vector<double>& row : m.rows) {
      EXPECT_EQ(row.size(), static_cast<std::size_t>(config_.ae2.latent_dim)) << m.model;
      for (double v : row)
        EXPECT_GE(v, 0.0) << m.model;
    }
  }
  EXPECT_TRUE(have_a);
  std::size_t steps = 0;
  for (const nlohmann::json& rec : records(run, "ae2"))
    steps += rec["model"] == "a";
  EXPECT_EQ(steps, 6u);
}

TEST_F(TrainerAe2, AStopInsideTheStageResumesToTheSameBytes) {
  const fs::path whole = train_to("whole", 3, options_);
  TrainOptions stopping = options_;
  stopping.on_checkpoint = [](const std::string& stage, std::int64_t step) {
    if (stage == "ae2 a" && step == 2)
      throw std::runtime_error("stopped at ae2 a step 2");
  };
  EXPECT_THROW(train_to("stopped", 3, stopping), std::runtime_error);
  const fs::path run = dir_ / "stopped";
  EXPECT_TRUE(fs::exists(run / "ae2.a.checkpoint.safetensors"));
  EXPECT_FALSE(fs::exists(run / "ae2.a.safetensors"));
  EXPECT_FALSE(RunDirectory::open(run).complete());
  train_to("stopped", 3, options_);
  EXPECT_TRUE(RunDirectory::open(run).complete());
  for (const char* f : {"ae2.a.safetensors", "ae2.b.safetensors", "ae2.lambda0.safetensors"})
    EXPECT_EQ(file_bytes(run / f), file_bytes(whole / f)) << f << " differs after the resume";
}

}  // namespace
}  // namespace ropes::crl::test_support
