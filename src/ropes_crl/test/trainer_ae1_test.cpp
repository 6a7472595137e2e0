// The trainer's stage 1 at the tiny preset's size: AE1 trained, every row encoded into
// codes.npy, the run not complete; and a run stopped inside the stage (the test hook throws
// after a checkpoint, as a kill would leave it) that resumes to the bytes of a run never
// stopped.
#include <ropes_core/npy.hpp>

#include <cmath>
#include <stdexcept>

#include "trainer_stage_fixture.hpp"

namespace ropes::crl::test_support {
namespace {

namespace fs = std::filesystem;

using TrainerAe1 = TrainerStage;

TEST_F(TrainerAe1, TrainsAe1AndEncodesEveryRow) {
  const fs::path run = train_to("run", 1, options_);
  EXPECT_TRUE(fs::exists(run / "ae1.safetensors"));
  EXPECT_FALSE(fs::exists(run / "ae1.checkpoint.safetensors"));  // removed at the end
  EXPECT_FALSE(fs::exists(run / "ldr.a.safetensors"));
  const RunDirectory r = RunDirectory::open(run);
  EXPECT_FALSE(r.complete());
  EXPECT_FALSE(r.ldr("a").has_value());
  // a code of every row (40 anchors x 5 regimes), AE1's code shape, finite
  const core::NpyArray codes = core::read_npy(r.codes_file());
  EXPECT_EQ(codes.dtype, core::DType::kF32);
  ASSERT_EQ(codes.shape.size(), 4u);
  EXPECT_EQ(codes.shape[0], 200);
  EXPECT_EQ(codes.shape[1], config_.ae1.code_channels);
  const float* v = reinterpret_cast<const float*>(codes.data.data());
  for (std::size_t i = 0; i < codes.data.size() / 4; ++i)
    ASSERT_TRUE(std::isfinite(v[i])) << "code value " << i;
  // a record a step (log_every 1), finite losses
  const std::vector<nlohmann::json> ae1 = records(run, "ae1");
  ASSERT_EQ(ae1.size(), 6u);
  for (std::size_t i = 0; i < ae1.size(); ++i) {
    EXPECT_EQ(ae1[i]["step"], i + 1);
    EXPECT_TRUE(std::isfinite(ae1[i]["loss"].get<double>()));
  }
}

TEST_F(TrainerAe1, AStopInsideTheStageResumesToTheSameBytes) {
  const fs::path whole = train_to("whole", 1, options_);
  TrainOptions stopping = options_;
  stopping.on_checkpoint = [](const std::string& stage, std::int64_t step) {
    if (stage == "ae1" && step == 4)
      throw std::runtime_error("stopped at ae1 step 4");
  };
  EXPECT_THROW(train_to("stopped", 1, stopping), std::runtime_error);
  const fs::path run = dir_ / "stopped";
  EXPECT_TRUE(fs::exists(run / "ae1.checkpoint.safetensors"));
  EXPECT_FALSE(fs::exists(run / "ae1.safetensors"));
  EXPECT_FALSE(fs::exists(run / "codes.npy"));
  train_to("stopped", 1, options_);
  for (const char* f : {"ae1.safetensors", "codes.npy"})
    EXPECT_EQ(file_bytes(run / f), file_bytes(whole / f)) << f << " differs after the resume";
  // the records of the steps after the checkpoint are written once
  EXPECT_EQ(records(run, "ae1").size(), 6u);
}

}  // namespace
}  // namespace ropes::crl::test_support
