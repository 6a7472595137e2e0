#pragma once
// What ropes_crl's tests train on without the simulator (ropes_crl does not link it): a
// synthetic two-joint dataset in the layout ropes-generate writes, and the tiny preset
// pointed at its joints with a few steps a stage.
#include <ropes_core/dataset.hpp>
#include <ropes_core/philox.hpp>
#include <ropes_crl/experiment_config.hpp>

#include <nlohmann/json.hpp>

#include <algorithm>
#include <cmath>
#include <cstdint>
#include <cstdio>
#include <cstring>
#include <filesystem>
#include <string>
#include <vector>

namespace ropes::crl::test_support {

inline const char* const kJoints[2] = {"a", "b"};

// joint j's bar, centred in its half of a size x size image, at angle q; camera 1 sees the
// transpose
inline void draw_bars(const double q[2], std::int64_t camera, std::int64_t size,
                      std::uint8_t* image) {
  const double half_length = 28.0 * static_cast<double>(size) / 128.0;
  const double half_width = std::max(1.0, 3.0 * static_cast<double>(size) / 128.0);
  for (std::int64_t y = 0; y < size; ++y)
    for (std::int64_t x = 0; x < size; ++x) {
      const std::int64_t u_px = camera == 0 ? x : y, v_px = camera == 0 ? y : x;
      const int j = u_px < size / 2 ? 0 : 1;
      const double u =
          static_cast<double>(u_px % (size / 2)) - static_cast<double>(size / 2 - 1) / 2.0;
      const double v = static_cast<double>(v_px) - static_cast<double>(size - 1) / 2.0;
      const double along = u * std::cos(q[j]) + v * std::sin(q[j]);
      const double across = -u * std::sin(q[j]) + v * std::cos(q[j]);
      image[y * size + x] =
          std::fabs(across) < half_width && std::fabs(along) < half_length ? 230 : 20;
    }
}

// 40 anchors x (observational, do(a)=1, do(a)=2, do(b)=1, do(b)=2) of size x size images,
// the columns and the metadata ropes-generate writes; without `observational` the metadata
// names a joint for regime 0, so no sample is observational; with `noise_angles` the angles
// column holds uniform noise on [-1.4, 1.4] instead of the angles drawn (the images are the
// same): a trainer that reads no angle trains to the same bytes on it
inline void write_two_bar_dataset(const std::filesystem::path& dir, std::int64_t cameras,
                                  std::int64_t size, bool observational = true,
                                  bool noise_angles = false) {
  const std::int64_t anchors = 40, regimes = 5, n = anchors * regimes;
  const std::int64_t pixels = cameras * size * size;
  core::NpyArray images{core::DType::kU8,
                        {n, cameras, size, size},
                        std::vector<std::uint8_t>(static_cast<std::size_t>(n * pixels))};
  core::NpyArray angles{core::DType::kF32, {n, 2}, std::vector<std::uint8_t>(n * 8)};
  core::NpyArray regime{core::DType::kI32, {n}, std::vector<std::uint8_t>(n * 4)};
  core::NpyArray anchor{core::DType::kI64, {n}, std::vector<std::uint8_t>(n * 8)};
  for (std::int64_t i = 0; i < n; ++i) {
    const std::int32_t r = static_cast<std::int32_t>(i % regimes);
    const std::int64_t a = i / regimes;
    core::PhiloxStream rng(9, static_cast<std::uint64_t>(i));
    core::PhiloxStream noise(10, static_cast<std::uint64_t>(i));  // noise_angles: the angles
    double q[2];
    for (int j = 0; j < 2; ++j) {
      const bool intervened = r != 0 && (r - 1) / 2 == j;
      const double mean = !intervened ? 0.0 : (r % 2 == 1 ? -0.6 : 0.6);
      const double sd = intervened ? 0.4 : 0.8;
      q[j] = mean + sd * rng.truncated_normal((-1.4 - mean) / sd, (1.4 - mean) / sd);
      const float qf =
          static_cast<float>(noise_angles ? 1.4 * (2 * noise.uniform_double() - 1) : q[j]);
      std::memcpy(&angles.data[static_cast<std::size_t>(i * 8 + j * 4)], &qf, 4);
    }
    for (std::int64_t c = 0; c < cameras; ++c)
      draw_bars(q, c, size, &images.data[static_cast<std::size_t>(i * pixels + c * size * size)]);
    std::memcpy(&regime.data[static_cast<std::size_t>(i * 4)], &r, 4);
    std::memcpy(&anchor.data[static_cast<std::size_t>(i * 8)], &a, 8);
  }
  const std::vector<core::ColumnSpec> columns = {
      {"images", core::DType::kU8, {cameras, size, size}},
      {"angles", core::DType::kF32, {2}},
      {"regime", core::DType::kI32, {}},
      {"anchor", core::DType::kI64, {}}};
  core::write_dataset_shard(dir, 0, columns, {images, angles, regime, anchor});
  nlohmann::json cams = nlohmann::json::array(), list = nlohmann::json::array();
  for (std::int64_t c = 0; c < cameras; ++c)
    cams.push_back("cam" + std::to_string(c));
  list.push_back({{"name", "observational"},
                  {"joint", observational ? nlohmann::json() : nlohmann::json("c")},
                  {"joint_index", nullptr},
                  {"intervention", nullptr}});
  nlohmann::json interventions;
  for (int j = 0; j < 2; ++j) {
    for (int k = 1; k <= 2; ++k)
      list.push_back({{"name", std::string("do(") + kJoints[j] + ")=" + std::to_string(k)},
                      {"joint", kJoints[j]},
                      {"joint_index", j},
                      {"intervention", k}});
    interventions[kJoints[j]] = {{{"mean", -0.6}, {"std", 0.4}, {"lower", -1.4}, {"upper", 1.4}},
                                 {{"mean", 0.6}, {"std", 0.4}, {"lower", -1.4}, {"upper", 1.4}}};
  }
  const nlohmann::json metadata = {{"cameras", cams},
                                   {"joint_names", {kJoints[0], kJoints[1]}},
                                   {"regimes", list},
                                   {"distribution", {{"interventions", interventions}}}};
  core::write_dataset_manifest(dir, columns, 1, metadata.dump());
}

// the installed-to-be config `file` (in ROPES_CRL_SOURCE_CONFIGS) pointed at the two joints,
// `steps` steps of AE1 and of AE2 without warm-up, `epochs` LDR epochs, a log record every
// step and a checkpoint every `checkpoint_every` steps
inline ExperimentConfig two_joint_config(const std::string& file, std::int64_t steps,
                                         std::int64_t epochs, std::int64_t checkpoint_every) {
  nlohmann::json raw =
      load_experiment_config(std::string(ROPES_CRL_SOURCE_CONFIGS) + "/" + file + ".json").raw;
  raw["dataset"]["joints"] = {kJoints[0], kJoints[1]};
  raw["ae1"]["steps"] = steps;
  raw["ae1"]["optimizer"]["warmup"] = 0;
  raw["ldr"]["max_epochs"] = epochs;
  raw["ae2"]["steps"] = steps;
  raw["ae2"]["optimizer"]["warmup"] = 0;
  raw["log_every"] = 1;
  raw["checkpoint_every"] = checkpoint_every;
  return ExperimentConfig::from_json(raw, file + " (a few steps, joints a and b)");
}

// a file's bytes (empty when it cannot be read)
inline std::vector<std::uint8_t> file_bytes(const std::filesystem::path& p) {
  std::FILE* f = std::fopen(p.c_str(), "rb");
  std::vector<std::uint8_t> out;
  if (f == nullptr)
    return out;
  std::uint8_t buf[65536];
  std::size_t n;
  while ((n = std::fread(buf, 1, sizeof buf, f)) > 0)
    out.insert(out.end(), buf, buf + n);
  std::fclose(f);
  return out;
}

}  // namespace ropes::crl::test_support
