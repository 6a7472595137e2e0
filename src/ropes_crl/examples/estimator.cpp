// Example from the ropes_crl README: ROPES on your own images, without the simulator. Writes
// a small dataset in ropes_core's container (a bar at angle q drawn into 32x32 images, under
// the paper's two shifted-mean interventions on q), trains the `tiny` preset on it with
// ropes-train's code, then loads the run with the Estimator and maps single frames to the
// latent that estimates q.
//
//   ropes_crl_example_estimator [DIR]   (default: a temporary directory, removed at the end)
#include <ropes_core/dataset.hpp>
#include <ropes_core/philox.hpp>
#include <ropes_crl/estimator.hpp>
#include <ropes_crl/trainer.hpp>

#include <unistd.h>

#include <cmath>
#include <cstdio>
#include <cstring>
#include <filesystem>

namespace fs = std::filesystem;
using namespace ropes;

// a bar through the image centre at angle q: u8 [32, 32]
void draw_bar(double q, std::uint8_t* image) {
  for (int y = 0; y < 32; ++y)
    for (int x = 0; x < 32; ++x) {
      const double u = x - 15.5, v = y - 15.5;
      const double along = u * std::cos(q) + v * std::sin(q);
      const double across = -u * std::sin(q) + v * std::cos(q);
      image[y * 32 + x] = std::fabs(across) < 2.0 && along > -2.0 && along < 14.0 ? 255 : 0;
    }
}

// 200 anchors x (observational, do(q)=1, do(q)=2): the columns ropes-generate writes
void write_dataset(const fs::path& dir) {
  const std::int64_t anchors = 200, n = anchors * 3;
  core::NpyArray images{core::DType::kU8, {n, 1, 32, 32}, std::vector<std::uint8_t>(n * 1024)};
  core::NpyArray angles{core::DType::kF32, {n, 1}, std::vector<std::uint8_t>(n * 4)};
  core::NpyArray regime{core::DType::kI32, {n}, std::vector<std::uint8_t>(n * 4)};
  core::NpyArray anchor{core::DType::kI64, {n}, std::vector<std::uint8_t>(n * 8)};
  const double means[3] = {0.0, -0.75, 0.75}, stds[3] = {1.0, 0.5, 0.5};
  for (std::int64_t i = 0; i < n; ++i) {
    const std::int32_t r = static_cast<std::int32_t>(i % 3);
    const std::int64_t a = i / 3;
    core::PhiloxStream rng(/*seed=*/3, /*stream=*/static_cast<std::uint64_t>(i));
    // TN(mean, std) on [-1.5, 1.5]
    const double z = rng.truncated_normal((-1.5 - means[r]) / stds[r], (1.5 - means[r]) / stds[r]);
    const float q = static_cast<float>(means[r] + stds[r] * z);
    draw_bar(q, &images.data[i * 1024]);
    std::memcpy(&angles.data[i * 4], &q, 4);
    std::memcpy(&regime.data[i * 4], &r, 4);
    std::memcpy(&anchor.data[i * 8], &a, 8);
  }
  const std::vector<core::ColumnSpec> columns = {{"images", core::DType::kU8, {1, 32, 32}},
                                                 {"angles", core::DType::kF32, {1}},
                                                 {"regime", core::DType::kI32, {}},
                                                 {"anchor", core::DType::kI64, {}}};
  core::write_dataset_shard(dir, 0, columns, {images, angles, regime, anchor});
  // what the trainer reads: the regimes by joint, the interventions' distributions (for the
  // LDR's Bayes accuracy), the joint names
  const nlohmann::json tn1 = {{"mean", -0.75}, {"variance", 0.5}, {"lower", -1.5}, {"upper", 1.5}};
  const nlohmann::json tn2 = {{"mean", 0.75}, {"variance", 0.5}, {"lower", -1.5}, {"upper", 1.5}};
  const nlohmann::json metadata = {
      {"cameras", {"cam0"}},
      {"joint_names", {"bar"}},
      {"regimes",
       {{{"name", "observational"},
         {"joint", nullptr},
         {"joint_index", nullptr},
         {"intervention", nullptr}},
        {{"name", "do(bar)=1"}, {"joint", "bar"}, {"joint_index", 0}, {"intervention", 1}},
        {{"name", "do(bar)=2"}, {"joint", "bar"}, {"joint_index", 0}, {"intervention", 2}}}},
      {"distribution", {{"interventions", {{"bar", {tn1, tn2}}}}}}};
  core::write_dataset_manifest(dir, columns, 1, metadata.dump());
}

int main(int argc, char** argv) {
  const bool scratch = argc < 2;
  const fs::path dir =
      scratch ? fs::temp_directory_path() / ("ropes_crl_example_" + std::to_string(::getpid()))
              : fs::path(argv[1]);
  try {
    if (!fs::exists(dir / "data" / "manifest.json"))
      write_dataset(dir / "data");

    // the installed tiny 1C preset, pointed at this dataset's one joint
    nlohmann::json raw = crl::load_experiment_config("1c-tiny").raw;
    raw["name"] = "bar-tiny";
    raw["dataset"]["config"] = "the example's own images";
    raw["dataset"]["joints"] = {"bar"};
    const crl::ExperimentConfig config = crl::ExperimentConfig::from_json(raw, "example");
    crl::TrainOptions options;
    options.seed = 1;
    options.threads = 2;
    crl::train(config, dir / "data", dir / "run", options);

    // the Estimator: one frame at a time, latent 0 estimates the bar's angle
    crl::Estimator estimator = crl::Estimator::load(dir / "run");
    std::vector<std::uint8_t> frame(32 * 32);
    std::printf("angle  latent\n");
    for (double q = -1.2; q <= 1.25; q += 0.6) {
      draw_bar(q, frame.data());
      float latent = 0;
      estimator.estimate_frame(frame.data(), &latent);
      std::printf("%5.2f  %7.4f\n", q, latent);
    }
    if (scratch)
      fs::remove_all(dir);
    return 0;
  } catch (const std::exception& e) {
    std::fprintf(stderr, "estimator example: %s\n", e.what());
    return 1;
  }
}
