#include "ropes_crl/experiment_config.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <stdexcept>

using namespace ropes::crl;
namespace fs = std::filesystem;

namespace {
std::string error_of(const nlohmann::json& j) {
  try {
    ExperimentConfig::from_json(j, "test.json");
  } catch (const std::invalid_argument& e) {
    return e.what();
  }
  return "";
}
}  // namespace

TEST(ExperimentConfig, EveryShippedConfigParses) {
  int count = 0;
  for (const auto& e : fs::directory_iterator(ROPES_CRL_SOURCE_CONFIGS)) {
    const ExperimentConfig c = load_experiment_config(e.path().string());
    EXPECT_EQ(c.name, e.path().stem().string());
    EXPECT_FALSE(c.deviations.empty()) << c.name << ": name how it departs from the paper";
    EXPECT_EQ(c.ldr.in_channels, c.cameras);
    ++count;
  }
  EXPECT_EQ(count, 9);  // {1c, 2c, 2c_causal} x {tiny, small, paper}
}

TEST(ExperimentConfig, ThePaperPresetIsTheAppendix) {
  const ExperimentConfig c =
      load_experiment_config(std::string(ROPES_CRL_SOURCE_CONFIGS) + "/1c-paper.json");
  EXPECT_EQ(c.ae1.widths, (std::vector<std::int64_t>{64, 128, 256, 512}));
  EXPECT_EQ(c.ae1.stem, "none");
  EXPECT_EQ(c.ae1_training.batch_size, 256);
  EXPECT_DOUBLE_EQ(c.ae1_training.optimizer.lr, 1e-4);
  EXPECT_DOUBLE_EQ(c.ldr_training.optimizer.lr, 1e-3);
  EXPECT_EQ(c.ldr_training.batch_size, 64);
  EXPECT_DOUBLE_EQ(c.ae2_training.optimizer.lr, 7e-5);
  EXPECT_EQ(c.ae2.kind, "conv");
  EXPECT_EQ(c.ae2.latent_dim, 3);
  ExperimentConfig e = c;
  e.resolve_epochs(70000);  // one epoch of the paper's 70k images
  EXPECT_EQ(e.ae1_training.steps, 274);
}

TEST(ExperimentConfig, ErrorsNameTheFileTheFieldAndTheValue) {
  const ExperimentConfig c =
      load_experiment_config(std::string(ROPES_CRL_SOURCE_CONFIGS) + "/1c-tiny.json");
  nlohmann::json j = c.raw;
  j["ae2"]["lambada"] = 1;
  EXPECT_NE(error_of(j).find("test.json: config.ae2.lambada: unknown key"), std::string::npos)
      << error_of(j);
  j = c.raw;
  j["ae2"]["sparsity_norm"] = "l3";
  EXPECT_NE(error_of(j).find("l3"), std::string::npos) << error_of(j);
  j = c.raw;
  j["ae2"]["sparsity_diagonal"] = "signed";
  EXPECT_NE(error_of(j).find("sparsity_diagonal: 'signed'"), std::string::npos) << error_of(j);
  j = c.raw;
  j["ldr"]["input_normalization"] = "whiten";
  EXPECT_NE(error_of(j).find("config.ldr.input_normalization: expected \"none\" or "
                             "\"standardize\", got \"whiten\""),
            std::string::npos)
      << error_of(j);
  j = c.raw;
  j["ae1"]["code_head"] = "sigmoid";
  EXPECT_NE(error_of(j).find("config.ae1.code_head: expected \"conv_relu\", \"linear\" or "
                             "\"resblock_linear\", got \"sigmoid\""),
            std::string::npos)
      << error_of(j);
  j = c.raw;
  j["ae2"]["input_normalization"] = 1;
  EXPECT_NE(error_of(j).find("config.ae2.input_normalization"), std::string::npos) << error_of(j);
  j = c.raw;
  j["ae2"]["score_normalization"] = "mean";
  EXPECT_NE(error_of(j).find("expected \"none\", \"unit\" or \"mean_unit\", got \"mean\""),
            std::string::npos)
      << error_of(j);
  j = c.raw;
  j["ae2"]["latent_dim"] = 2;  // three joints need three latents
  EXPECT_NE(error_of(j).find("config.ae2.latent_dim: 2"), std::string::npos) << error_of(j);
  j = c.raw;
  j["ae1"].erase("optimizer");
  EXPECT_NE(error_of(j).find("config.ae1.optimizer: missing"), std::string::npos) << error_of(j);
  // a name is never a path: ropes-run's default output is runs/<name>
  for (const char* name : {"../../tmp/x", "/etc/x", ".hidden", "a/b", ""}) {
    j = c.raw;
    j["name"] = name;
    EXPECT_NE(error_of(j).find("config.name: expected a plain name"), std::string::npos)
        << name << ": " << error_of(j);
  }
  j = c.raw;
  j["ae1"]["epochs"] = 1;  // beside "steps"
  EXPECT_NE(error_of(j).find("exactly one of"), std::string::npos) << error_of(j);
  try {
    load_experiment_config("no-such-config");
    FAIL();
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("'no-such-config' is neither a file nor an installed"),
              std::string::npos);
  }
}
