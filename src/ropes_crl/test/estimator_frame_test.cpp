// Estimator::estimate_frame, the call streaming makes per frame: after warm-up it allocates
// nothing (at one to four threads, one and two cameras, per-joint and joint AE2s, standardised
// LDRs and AE2s), it gives
// the same bits at every thread count, and it gives the latents the batch
// evaluation gives — bit for bit for a batch of one, to float rounding inside a larger batch
// (there the MLP's products are a GEMM instead of a GEMV). The run is the `small` preset's
// architecture, trained for a few steps on a synthetic two-joint dataset (what is tested is
// the inference path, not the learning). Its own executable: allocation_counter.hpp
// interposes malloc for the whole process.
#include <ropes_crl/estimator.hpp>
#include <ropes_crl/trainer.hpp>
#include <ropes_nn/allocation_counter.hpp>
#include <ropes_nn/checkpoint.hpp>
#include <ropes_nn/parallel.hpp>
#include <ropes_nn/safetensors.hpp>

#include <gtest/gtest.h>
#include <unistd.h>

#include <algorithm>
#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <stdexcept>
#include <string>
#include <vector>

#include "synthetic_run.hpp"

namespace ropes::crl {
namespace {

namespace fs = std::filesystem;
constexpr std::int64_t kSize = 128;

using test_support::file_bytes;
using test_support::kJoints;

// joint j's bar at angle q in camera `camera`'s kSize x kSize image (synthetic_run.hpp)
void draw(const double q[2], std::int64_t camera, std::uint8_t* image) {
  test_support::draw_bars(q, camera, kSize, image);
}

// the synthetic two-joint dataset (synthetic_run.hpp) at kSize
void write_dataset(const fs::path& dir, std::int64_t cameras, bool observational = true) {
  test_support::write_two_bar_dataset(dir, cameras, kSize, observational);
}

// the small preset `name` ("1c-small", or "1c-small/joint" for one AE2 of every joint),
// pointed at the two joints, a few steps per stage
ExperimentConfig few_steps(const std::string& name) {
  const std::string file = name.substr(0, name.find('/'));
  nlohmann::json raw =
      load_experiment_config(std::string(ROPES_CRL_SOURCE_CONFIGS) + "/" + file + ".json").raw;
  if (name.find("/joint") != std::string::npos)
    raw["ae2"]["mode"] = "joint";
  if (name.find("/standardized") != std::string::npos) {
    raw["ldr"]["input_normalization"] = "standardize";
    raw["ae2"]["input_normalization"] = "standardize";
  }
  raw["dataset"]["joints"] = {kJoints[0], kJoints[1]};
  raw["ae1"]["steps"] = 3;
  raw["ae1"]["optimizer"]["warmup"] = 0;
  raw["ldr"]["max_epochs"] = 1;
  raw["ae2"]["steps"] = 3;
  raw["ae2"]["optimizer"]["warmup"] = 0;
  raw["log_every"] = 1;
  return ExperimentConfig::from_json(raw, name + " (few steps)");
}

class EstimatorFrame : public ::testing::TestWithParam<const char*> {
 protected:
  void SetUp() override {
    std::string tag = GetParam();
    std::replace(tag.begin(), tag.end(), '/', '_');
    dir_ =
        fs::temp_directory_path() / ("ropes_crl_frame_" + std::to_string(::getpid()) + "_" + tag);
    fs::remove_all(dir_);
    const ExperimentConfig config = few_steps(GetParam());
    write_dataset(dir_ / "data", config.cameras);
    TrainOptions options;
    options.threads = 2;
    train(config, dir_ / "data", dir_ / "run", options);
  }
  void TearDown() override {
    nn::set_num_threads(2);
    fs::remove_all(dir_);
  }
  fs::path dir_;
};

TEST_P(EstimatorFrame, AllocatesNothingAfterWarmUpAndMatchesTheBatchPath) {
  Estimator estimator = Estimator::load(dir_ / "run");
  const std::int64_t cameras = estimator.cameras(), pixels = cameras * kSize * kSize;
  // five frames of the training distribution's range
  const std::int64_t frames = 5;
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(frames * pixels));
  nn::Buffer values(bytes.size());
  for (std::int64_t f = 0; f < frames; ++f) {
    const double q[2] = {-1.2 + 0.6 * static_cast<double>(f), 0.9 - 0.45 * static_cast<double>(f)};
    for (std::int64_t c = 0; c < cameras; ++c)
      draw(q, c, &bytes[static_cast<std::size_t>(f * pixels + c * kSize * kSize)]);
  }
  for (std::size_t i = 0; i < bytes.size(); ++i)
    values[i] = static_cast<float>(bytes[i]) / 255.0f;
  const nn::Tensor batch(nn::Shape{frames, cameras, kSize, kSize}, values);

  Calibration calibration;
  calibration.joints = estimator.joints();
  calibration.scale = {0.5, -2.0};
  calibration.offset = {0.25, 1.0};
  estimator.set_calibration(calibration);

  std::vector<float> at_one_thread;
  // 3 and 4 threads oversubscribe 2 cores, which is fine: OpenMP teams of several sizes are
  // what made warm calls allocate
  for (int threads : {1, 2, 3, 4}) {
    nn::set_num_threads(threads);
    const nn::Tensor together = estimator.latents(batch);
    float latents[2], angles[2];
    for (int i = 0; i < 3; ++i)  // warm-up: the pool and the product workspaces fill
      estimator.estimate_frame(bytes.data(), latents, angles);
    nn::allocation_counter::start();
    for (int i = 0; i < 20; ++i)
      estimator.estimate_frame(&bytes[static_cast<std::size_t>((i % frames) * pixels)], latents,
                               angles);
    const std::uint64_t allocations = nn::allocation_counter::stop();
    if (nn::allocation_counter::available) {  // not in a sanitizer build: it counts nothing
      EXPECT_EQ(allocations, 0u) << threads << " thread(s)";
    }

    std::vector<float> all;
    for (std::int64_t f = 0; f < frames; ++f) {
      estimator.estimate_frame(&bytes[static_cast<std::size_t>(f * pixels)], latents, angles);
      all.insert(all.end(), latents, latents + 2);
      const nn::Tensor alone = estimator.latents(nn::slice(batch, 0, f, f + 1));
      for (int k = 0; k < 2; ++k) {
        EXPECT_EQ(latents[k], alone.data()[k]) << "frame " << f << ", joint " << k;
        EXPECT_NEAR(latents[k], together.data()[f * 2 + k], 1e-5 * (1 + std::fabs(latents[k])))
            << "frame " << f << ", joint " << k;
        EXPECT_FLOAT_EQ(angles[k], static_cast<float>(calibration.scale[k] * latents[k] +
                                                      calibration.offset[k]));
      }
    }
    // a frame's estimate does not depend on the thread count, bit for bit
    if (at_one_thread.empty())
      at_one_thread = all;
    EXPECT_EQ(all, at_one_thread) << threads << " thread(s) against 1";
  }
}

// The report's reconstructions: AE1's is its own network's decode(encode(x)) camera by
// camera (checked against an Ae1 loaded from the run's file), and the one through joint k's
// AE2 decodes AE2's reconstruction of Y — with standardised codes mapped back to Y's
// coordinates first: for a standardised run it is checked against Y = s / scale + shift
// computed here from the saved map
TEST_P(EstimatorFrame, ReconstructsThroughAe1AndThroughEachAe2) {
  Estimator estimator = Estimator::load(dir_ / "run");
  const ExperimentConfig& c = estimator.config();
  const std::int64_t cameras = c.cameras, n = 3;
  std::vector<std::uint8_t> bytes(static_cast<std::size_t>(n * cameras * kSize * kSize));
  nn::Buffer values(bytes.size());
  for (std::int64_t f = 0; f < n; ++f) {
    const double q[2] = {-0.8 + 0.7 * static_cast<double>(f), 0.4 * static_cast<double>(f)};
    for (std::int64_t cam = 0; cam < cameras; ++cam)
      draw(q, cam, &bytes[static_cast<std::size_t>((f * cameras + cam) * kSize * kSize)]);
  }
  for (std::size_t i = 0; i < bytes.size(); ++i)
    values[i] = static_cast<float>(bytes[i]) / 255.0f;
  const nn::Tensor x(nn::Shape{n, cameras, kSize, kSize}, values);
  const nn::Tensor r = estimator.reconstruct(x);
  ASSERT_EQ(r.shape(), x.shape());
  Ae1 ae1(c.ae1);
  nn::load_module(ae1, dir_ / "run" / "ae1.safetensors");
  nn::GradModeGuard no_grad(false);
  const nn::Tensor own = ae1(nn::reshape(x, nn::Shape{n * cameras, 1, kSize, kSize}));
  for (std::int64_t i = 0; i < own.numel(); ++i)
    ASSERT_EQ(r.data()[i], own.data()[i]) << i;
  for (std::size_t k = 0; k < estimator.joints().size(); ++k) {
    const nn::Tensor through = estimator.reconstruct_through_ae2(x, k);
    ASSERT_EQ(through.shape(), x.shape());
    // by hand: Y, AE2 of joint k, back to Y's coordinates, AE1's decoder
    Ae2 ae2(c.ae2);
    nn::load_module(ae2, dir_ / "run" /
                             ("ae2." +
                              (c.ae2_training.mode == "per_joint" ? estimator.joints()[k]
                                                                  : std::string("joint")) +
                              ".safetensors"));
    const nn::Tensor y = estimator.codes(x);
    const nn::Tensor in_ae2 = ae2.decode(ae2.encode(y));  // AE2's coordinates
    nn::Tensor back = in_ae2;
    if (const CodeStandardization* map = ae2.input_map()) {
      std::vector<float> v(back.data(), back.data() + back.numel());
      for (std::int64_t i = 0; i < back.numel(); ++i) {
        const float sc = map->scale().data()[i % map->scale().numel()];
        const float sh = map->shift().data()[i % map->shift().numel()];
        v[static_cast<std::size_t>(i)] = sc != 0.0f ? v[static_cast<std::size_t>(i)] / sc + sh : sh;
      }
      back = nn::Tensor(back.shape(), v);
      // the map back inverts the map: AE2's coordinates of `back` are what AE2 gave, where
      // the map keeps an element (scale != 0)
      const nn::Tensor again = ae2.coordinates(back);
      for (std::int64_t i = 0; i < again.numel(); ++i) {
        if (map->scale().data()[i % map->scale().numel()] == 0.0f)
          continue;
        ASSERT_NEAR(again.data()[i], in_ae2.data()[i], 1e-4 * (1 + std::fabs(in_ae2.data()[i])))
            << i;
      }
    }
    const std::int64_t side = y.shape()[2];
    const nn::Tensor want =
        ae1.decode(nn::reshape(back, nn::Shape{n * cameras, y.shape()[1] / cameras, side, side}));
    for (std::int64_t i = 0; i < want.numel(); ++i)
      ASSERT_EQ(through.data()[i], want.data()[i]) << "joint " << k << ", value " << i;
  }
  EXPECT_THROW(estimator.reconstruct_through_ae2(x, 2), std::invalid_argument);
}

// With both standardisations every LDR and AE2 carries the one map the trainer fitted, and
// it is not the untrained identity
class StandardizedRun : public EstimatorFrame {};

TEST_P(StandardizedRun, EveryNetworkCarriesTheOneFittedMap) {
  std::vector<std::uint8_t> shift, scale;
  int files = 0;
  for (const auto& entry : fs::directory_iterator(dir_ / "run")) {
    const std::string name = entry.path().filename().string();
    if ((name.rfind("ldr.", 0) != 0 && name.rfind("ae2.", 0) != 0) ||
        entry.path().extension() != ".safetensors")
      continue;
    const nn::Safetensors file = nn::read_safetensors(entry.path());
    const core::NpyArray* a = file.find("input.shift");
    const core::NpyArray* b = file.find("input.scale");
    ASSERT_TRUE(a != nullptr && b != nullptr) << name;
    if (files++ == 0) {
      shift = a->data;
      scale = b->data;
    }
    EXPECT_EQ(a->data, shift) << name;
    EXPECT_EQ(b->data, scale) << name;
  }
  EXPECT_EQ(files, 2 + 3);  // two LDRs, two AE2s and the lambda = 0 one
  std::vector<float> values(scale.size() / 4);
  std::memcpy(values.data(), scale.data(), scale.size());
  EXPECT_TRUE(std::any_of(values.begin(), values.end(), [](float v) { return v != 1.0f; }));
}

// Stage 3 trains two AE2s side by side at 2 threads. When one fails (here the test hook
// throws at its step-10 checkpoint), the other stops at its next step with a checkpoint,
// the model waiting for a free worker (the lambda = 0 AE2) never starts, and the first
// failure reaches the caller; started again, the run ends in the bytes of a run never
// stopped.
// AE1's difference loss pairs each sample with its anchor's observational sample: a dataset
// without observational samples is refused before AE1 trains, naming it, the anchor and the row
TEST(DifferenceLoss, ADatasetWithoutObservationalSamplesIsRefused) {
  const fs::path dir =
      fs::temp_directory_path() / ("ropes_crl_no_observational_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  const ExperimentConfig config = few_steps("1c-small");
  ASSERT_GT(config.ae1_training.difference_loss.weight, 0.0) << "1c-small uses the loss";
  write_dataset(dir / "data", config.cameras, false);
  TrainOptions options;
  options.threads = 2;
  try {
    train(config, dir / "data", dir / "run", options);
    ADD_FAILURE() << "a dataset without observational samples was trained on";
  } catch (const std::invalid_argument& e) {
    const std::string what = e.what();
    EXPECT_NE(what.find("config.ae1.difference_loss pairs each sample with its anchor's "
                        "observational sample; " +
                        (dir / "data").string() + " has none for anchor 0 (row 0)"),
              std::string::npos)
        << what;
  }
  EXPECT_FALSE(fs::exists(dir / "run" / "ae1.safetensors"));
  nn::set_num_threads(2);
  fs::remove_all(dir);
}

TEST(SideBySideAe2s, OneFailureStopsTheOthersWithACheckpointAndTheRunResumes) {
  const fs::path dir =
      fs::temp_directory_path() / ("ropes_crl_side_by_side_" + std::to_string(::getpid()));
  fs::remove_all(dir);
  ExperimentConfig config = few_steps("1c-small");
  // 400 steps: the other AE2 is far from done when the first fails at step 10
  config.ae2_training.steps = 400;
  config.checkpoint_every = 10;
  write_dataset(dir / "data", config.cameras);
  TrainOptions options;
  options.threads = 2;
  train(config, dir / "data", dir / "whole", options);

  const std::string failing = std::string("ae2 ") + kJoints[0];
  TrainOptions hooked = options;
  hooked.on_checkpoint = [&](const std::string& stage, std::int64_t step) {
    if (stage == failing && step == 10)
      throw std::runtime_error("injected failure of " + stage);
  };
  const fs::path run = dir / "stopped";
  try {
    train(config, dir / "data", run, hooked);
    ADD_FAILURE() << "the injected failure did not reach the caller";
  } catch (const std::runtime_error& e) {
    EXPECT_EQ(std::string(e.what()), "injected failure of " + failing);
  }
  const std::string other = std::string("ae2.") + kJoints[1];
  EXPECT_FALSE(fs::exists(run / (std::string("ae2.") + kJoints[0] + ".safetensors")));
  EXPECT_TRUE(fs::exists(run / (std::string("ae2.") + kJoints[0] + ".checkpoint.safetensors")));
  // the other one stopped short of its end, with a checkpoint of the step it reached
  EXPECT_TRUE(fs::exists(run / (other + ".checkpoint.safetensors")));
  EXPECT_FALSE(fs::exists(run / (other + ".safetensors")));
  EXPECT_FALSE(fs::exists(run / "ae2.lambda0.safetensors"));
  EXPECT_FALSE(fs::exists(run / "ae2.lambda0.checkpoint.safetensors"));

  train(config, dir / "data", run, options);
  for (const char* f : {"ae2.a.safetensors", "ae2.b.safetensors", "ae2.lambda0.safetensors"})
    EXPECT_EQ(file_bytes(run / f), file_bytes(dir / "whole" / f)) << f << " differs";
  EXPECT_FALSE(file_bytes(run / "ae2.lambda0.safetensors").empty());
  nn::set_num_threads(2);
  fs::remove_all(dir);
}

INSTANTIATE_TEST_SUITE_P(SmallPreset, EstimatorFrame,
                         ::testing::Values("1c-small", "2c-small", "1c-small/joint",
                                           "1c-small/standardized"),
                         [](const auto& param_info) {
                           const std::string p = param_info.param;
                           if (p == "1c-small/joint")
                             return std::string("OneCameraJointMode");
                           if (p == "1c-small/standardized")
                             return std::string("OneCameraStandardized");
                           return std::string(p == "1c-small" ? "OneCamera" : "TwoCameras");
                         });
INSTANTIATE_TEST_SUITE_P(SmallPreset, StandardizedRun, ::testing::Values("1c-small/standardized"),
                         [](const auto&) { return std::string("OneCamera"); });

}  // namespace
}  // namespace ropes::crl
