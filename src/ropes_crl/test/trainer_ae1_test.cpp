// The trainer's stage 1 at the tiny preset's size: AE1 trained, every row encoded into
// codes.npy, the run not complete; and a run stopped inside the stage (the test hook throws
// after a checkpoint, as a kill would leave it) that resumes to the bytes of a run never
// stopped.
#include <ropes_core/npy.hpp>
#include <ropes_crl/networks.hpp>
#include <ropes_nn/checkpoint.hpp>

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

// AE1 with the pair heads (an extension): 2 pairs a joint a step, heads of `head`
void add_pair_heads(ExperimentConfig& config, const std::string& head = "ldr") {
  nlohmann::json raw = config.raw;
  raw["ae1"]["pair_heads"] = {{"weight", 1.0}, {"pairs_per_joint", 2}, {"head", head}};
  config = ExperimentConfig::from_json(raw, "1c-tiny with pair heads");
}

class TrainerAe1PairHeads : public TrainerStage,
                            public ::testing::WithParamInterface<std::string> {};

TEST_P(TrainerAe1PairHeads, TrainWithAe1AndLogTheirTerm) {
  add_pair_heads(config_, GetParam());
  const fs::path run = train_to("run", 1, options_);
  EXPECT_TRUE(fs::exists(run / "ae1.safetensors"));
  EXPECT_FALSE(fs::exists(run / "ae1.checkpoint.safetensors"));
  const std::vector<nlohmann::json> ae1 = records(run, "ae1");
  ASSERT_EQ(ae1.size(), 6u);
  for (const nlohmann::json& r : ae1) {
    const double loss = r.at("pair_loss").get<double>(), right = r.at("pair_accuracy");
    EXPECT_TRUE(std::isfinite(loss) && loss > 0) << r.dump();
    // 4 pairs a step (2 joints x 2): a fraction in quarters
    EXPECT_DOUBLE_EQ(right * 4, std::round(right * 4)) << r.dump();
  }
  // the heads are trained with AE1 but not saved with it: the file loads as a plain AE1
  Ae1 net(config_.ae1);
  EXPECT_NO_THROW(nn::load_module(net, run / "ae1.safetensors"));
}

INSTANTIATE_TEST_SUITE_P(Heads, TrainerAe1PairHeads, ::testing::Values("ldr", "linear"));

// The extensions read regimes and anchors, never an angle: on a dataset whose angles column
// is noise (the same images, regimes and anchors) a run with AE1's pair heads, occlusion
// augmentation and difference loss, the LDRs' pair loss and weight average and AE2's logit
// term comes out byte for byte the same in every weight file of every stage. And the extensions do
// change the networks, so the comparison is not one of untouched ones.
TEST_F(TrainerAe1, TheExtensionsReadNoAngle) {
  const fs::path noise = dir_ / "noise";
  write_two_bar_dataset(noise, config_.cameras, config_.image_size, true, true);
  ASSERT_NE(file_bytes(noise / "shards" / "angles-00000.npy"),
            file_bytes(data() / "shards" / "angles-00000.npy"))
      << "the noise dataset's angles differ from the drawn ones";
  const fs::path plain = train_to("plain", 3, options_);
  add_pair_heads(config_);
  nlohmann::json raw = config_.raw;
  raw["ldr"]["pair_loss"] = {{"weight", 1.0}};
  raw["ldr"]["weight_average"] = {{"decay", 0.9}};
  raw["ae2"]["logit_loss"] = {{"weight", 1.0}};
  raw["ae1"]["occlusion_augmentation"] = {
      {"probability", 0.5}, {"min_size", 2}, {"max_size", config_.image_size / 2}};
  raw["ae1"]["difference_loss"] = {{"weight", 0.05}};
  config_ = ExperimentConfig::from_json(raw, "1c-tiny with the extensions");
  const fs::path extended = train_to("extended", 3, options_);
  TrainOptions o = options_;
  o.last_stage = 3;
  train(config_, noise, dir_ / "extended_noise", o);
  for (const char* f : {"ae1.safetensors", "codes.npy", "ldr.a.safetensors", "ldr.b.safetensors",
                        "ae2.a.safetensors", "ae2.b.safetensors"}) {
    EXPECT_EQ(file_bytes(dir_ / "extended_noise" / f), file_bytes(extended / f))
        << f << ": the angles reached the training";
    EXPECT_NE(file_bytes(plain / f), file_bytes(extended / f))
        << f << ": the extensions changed nothing";
  }
}

// With occlusion augmentation and the difference loss, a pair whose images got squares
// counts in the reconstruction term only. With every image occluded (probability 1) the
// difference term's weight therefore changes nothing: weights 0.05 and 5 give the same codes.
// With half of them occluded it does change them, so the comparison can fail.
TEST_F(TrainerAe1, AnOccludedPairLeavesTheDifferenceTerm) {
  const auto codes_with = [&](double probability, double weight, const std::string& name) {
    nlohmann::json raw = config_.raw;
    raw["ae1"]["occlusion_augmentation"] = {
        {"probability", probability}, {"min_size", 2}, {"max_size", config_.image_size / 2}};
    raw["ae1"]["difference_loss"] = {{"weight", weight}};
    const ExperimentConfig saved = config_;
    config_ = ExperimentConfig::from_json(raw, "1c-tiny, " + name);
    const fs::path run = train_to(name, 1, options_);
    config_ = saved;
    return file_bytes(run / "codes.npy");
  };
  EXPECT_EQ(codes_with(1.0, 0.05, "all_small"), codes_with(1.0, 5.0, "all_large"))
      << "a pair with squares reached the difference term";
  EXPECT_NE(codes_with(0.5, 0.05, "half_small"), codes_with(0.5, 5.0, "half_large"))
      << "the difference term's weight changed nothing with half of the images clean";
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

TEST_F(TrainerAe1, AStopWithPairHeadsResumesToTheSameBytes) {
  add_pair_heads(config_);
  const fs::path whole = train_to("whole", 1, options_);
  TrainOptions stopping = options_;
  stopping.on_checkpoint = [](const std::string& stage, std::int64_t step) {
    if (stage == "ae1" && step == 2)
      throw std::runtime_error("stopped at ae1 step 2");
  };
  EXPECT_THROW(train_to("stopped", 1, stopping), std::runtime_error);
  const fs::path run = dir_ / "stopped";
  ASSERT_TRUE(fs::exists(run / "ae1.checkpoint.safetensors"));
  train_to("stopped", 1, options_);
  for (const char* f : {"ae1.safetensors", "codes.npy"})
    EXPECT_EQ(file_bytes(run / f), file_bytes(whole / f)) << f << " differs after the resume";
  // the same pairs drawn after the resume: the same pair terms, each step logged once
  const std::vector<nlohmann::json> resumed = records(run, "ae1"), once = records(whole, "ae1");
  ASSERT_EQ(resumed.size(), once.size());
  for (std::size_t i = 0; i < once.size(); ++i)
    EXPECT_EQ(resumed[i]["pair_loss"], once[i]["pair_loss"]) << "step " << i + 1;
}

}  // namespace
}  // namespace ropes::crl::test_support
