#include "ropes_crl/experiment_config.hpp"
#include "ropes_crl/trainer.hpp"

#include <gtest/gtest.h>
#include <ropes_core/file_format_error.hpp>
#include <ropes_nn/gradcheck.hpp>

#include <algorithm>
#include <filesystem>
#include <stdexcept>

using namespace ropes::crl;
namespace nn = ropes::nn;
namespace fs = std::filesystem;

namespace {
std::string error_of(const nlohmann::json& j) {
  try {
    ExperimentConfig::from_json(j, "test.json");
  } catch (const ropes::core::ConfigError& e) {
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
  // {1c, 2c, 2c_causal} x {tiny, small, small-plus, paper}, and 2c-small-plus-occlusion
  EXPECT_EQ(count, 13);
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
  // the occlusion augmentation (an extension, off when absent): an object of three fields
  j = c.raw;
  j["ae1"]["occlusion_augmentation"] = 0.5;
  EXPECT_NE(error_of(j).find("config.ae1.occlusion_augmentation: expected an object"),
            std::string::npos)
      << error_of(j);
  j["ae1"]["occlusion_augmentation"] = {{"probability", 1.5}, {"min_size", 8}, {"max_size", 16}};
  EXPECT_NE(error_of(j).find("config.ae1.occlusion_augmentation.probability: expected in (0, 1], "
                             "got 1.5"),
            std::string::npos)
      << error_of(j);
  j["ae1"]["occlusion_augmentation"] = {{"probability", 0.5}, {"min_size", 8}, {"max_size", 900}};
  EXPECT_NE(error_of(j).find("config.ae1.occlusion_augmentation: min_size 8, max_size 900; "
                             "expected 1 <= min_size <= max_size <= the image's"),
            std::string::npos)
      << error_of(j);
  j["ae1"]["occlusion_augmentation"] = {{"probability", 0.5}, {"min_size", 8}, {"size", 9}};
  EXPECT_NE(error_of(j).find("config.ae1.occlusion_augmentation"), std::string::npos)
      << error_of(j);
  j["ae1"]["occlusion_augmentation"] = {{"probability", 0.5}, {"min_size", 8}, {"max_size", 16}};
  EXPECT_EQ(error_of(j), "");
  EXPECT_DOUBLE_EQ(
      ExperimentConfig::from_json(j, "test.json").ae1_training.occlusion_augmentation.probability,
      0.5);
  EXPECT_DOUBLE_EQ(c.ae1_training.occlusion_augmentation.probability, 0.0) << "off when absent";
  // the difference loss (a variant, off when absent): {"weight" > 0}, an even number of
  // samples a step; the occlusion augmentation may come with it
  j = c.raw;
  j["ae1"]["difference_loss"] = 1;
  EXPECT_NE(error_of(j).find("config.ae1.difference_loss: expected an object {\"weight\"}, got a "
                             "number"),
            std::string::npos)
      << error_of(j);
  j["ae1"]["difference_loss"] = {{"weight", 0}};
  EXPECT_NE(error_of(j).find("config.ae1.difference_loss.weight: expected in (0, 1e6], got 0"),
            std::string::npos)
      << error_of(j);
  j["ae1"]["difference_loss"] = {{"weight", 1}, {"floor", 1}};
  EXPECT_NE(error_of(j).find("config.ae1.difference_loss"), std::string::npos) << error_of(j);
  j["ae1"]["difference_loss"] = {{"weight", 4}};
  j["ae1"]["batch_size"] = 6 * c.cameras + c.cameras;  // 7 samples
  EXPECT_NE(error_of(j).find("is 7 samples a step; expected an even number"), std::string::npos)
      << error_of(j);
  j["ae1"]["batch_size"] = c.raw["ae1"]["batch_size"];
  j["ae1"]["occlusion_augmentation"] = {{"probability", 0.5}, {"min_size", 8}, {"max_size", 16}};
  EXPECT_EQ(error_of(j), "");
  j["ae1"].erase("occlusion_augmentation");
  EXPECT_EQ(error_of(j), "");
  EXPECT_DOUBLE_EQ(ExperimentConfig::from_json(j, "test.json").ae1_training.difference_loss.weight,
                   4.0);
  EXPECT_DOUBLE_EQ(c.ae1_training.difference_loss.weight, 0.0) << "off when absent";
  // the pair heads (an extension, off when absent): {"weight" > 0, "pairs_per_joint" >= 1}
  j = c.raw;
  j["ae1"]["pair_heads"] = 0.5;
  EXPECT_NE(error_of(j).find("config.ae1.pair_heads: expected an object {\"weight\", "
                             "\"pairs_per_joint\"}, got a number"),
            std::string::npos)
      << error_of(j);
  j["ae1"]["pair_heads"] = {{"weight", -1}, {"pairs_per_joint", 1}};
  EXPECT_NE(error_of(j).find("config.ae1.pair_heads.weight: expected in (0, 1e6], got -1"),
            std::string::npos)
      << error_of(j);
  j["ae1"]["pair_heads"] = {{"weight", 1}, {"pairs_per_joint", 0}};
  EXPECT_NE(error_of(j).find("config.ae1.pair_heads.pairs_per_joint: expected in [1, 4096], got 0"),
            std::string::npos)
      << error_of(j);
  j["ae1"]["pair_heads"] = {{"weight", 1}};
  EXPECT_NE(error_of(j).find("config.ae1.pair_heads"), std::string::npos) << error_of(j);
  j["ae1"]["pair_heads"] = {{"weight", 1}, {"pairs_per_joint", 2}, {"joint", "a"}};
  EXPECT_NE(error_of(j).find("config.ae1.pair_heads.joint: unknown key"), std::string::npos)
      << error_of(j);
  j["ae1"]["pair_heads"] = {{"weight", 1}, {"pairs_per_joint", 2}, {"head", "conv"}};
  EXPECT_NE(error_of(j).find("config.ae1.pair_heads.head: expected \"ldr\" or \"linear\", got "
                             "\"conv\""),
            std::string::npos)
      << error_of(j);
  j["ae1"]["pair_heads"] = {{"weight", 0.25}, {"pairs_per_joint", 3}};
  EXPECT_EQ(error_of(j), "");
  {
    const PairHeads h = ExperimentConfig::from_json(j, "test.json").ae1_training.pair_heads;
    EXPECT_DOUBLE_EQ(h.weight, 0.25);
    EXPECT_EQ(h.pairs_per_joint, 3);
    EXPECT_EQ(h.head, "ldr") << "the LDR's architecture when absent";
  }
  j["ae1"]["pair_heads"]["head"] = "linear";
  EXPECT_EQ(ExperimentConfig::from_json(j, "test.json").ae1_training.pair_heads.head, "linear");
  EXPECT_DOUBLE_EQ(c.ae1_training.pair_heads.weight, 0.0) << "off when absent";
  // the LDRs' pair loss (an extension, off when absent): {"weight" > 0}
  j = c.raw;
  j["ldr"]["pair_loss"] = "yes";
  EXPECT_NE(error_of(j).find("config.ldr.pair_loss: expected an object {\"weight\"}, got a "
                             "string"),
            std::string::npos)
      << error_of(j);
  j["ldr"]["pair_loss"] = {{"weight", 0}};
  EXPECT_NE(error_of(j).find("config.ldr.pair_loss.weight: expected in (0, 1e6], got 0"),
            std::string::npos)
      << error_of(j);
  j["ldr"]["pair_loss"] = {{"weight", 2}, {"pairs", 1}};
  EXPECT_NE(error_of(j).find("config.ldr.pair_loss.pairs: unknown key"), std::string::npos)
      << error_of(j);
  j["ldr"]["pair_loss"] = {{"weight", 2}};
  EXPECT_DOUBLE_EQ(ExperimentConfig::from_json(j, "test.json").ldr_training.pair_loss.weight, 2.0);
  EXPECT_DOUBLE_EQ(c.ldr_training.pair_loss.weight, 0.0) << "off when absent";
  // an ensemble of LDRs (an extension, one classifier when absent): 1 to 16 members
  j = c.raw;
  j["ldr"]["members"] = 0;
  EXPECT_NE(error_of(j).find("config.ldr.members: expected 1 to 16 classifiers, got 0"),
            std::string::npos)
      << error_of(j);
  j["ldr"]["members"] = 1.5;
  EXPECT_NE(error_of(j).find("config.ldr.members"), std::string::npos) << error_of(j);
  j["ldr"]["members"] = 3;
  EXPECT_EQ(ExperimentConfig::from_json(j, "test.json").ldr.members, 3);
  EXPECT_EQ(c.ldr.members, 1) << "one classifier when absent";
  // the LDRs' weight average (an extension, off when absent): {"decay" in (0, 1)}
  j = c.raw;
  j["ldr"]["weight_average"] = 0.99;
  EXPECT_NE(error_of(j).find("config.ldr.weight_average: expected an object {\"decay\"}, got a "
                             "number"),
            std::string::npos)
      << error_of(j);
  j["ldr"]["weight_average"] = {{"decay", 1}};
  EXPECT_NE(error_of(j).find("config.ldr.weight_average.decay: expected in (0, 1), got 1"),
            std::string::npos)
      << error_of(j);
  j["ldr"]["weight_average"] = {{"decay", 0.9}, {"start", 2}};
  EXPECT_NE(error_of(j).find("config.ldr.weight_average.start: unknown key"), std::string::npos)
      << error_of(j);
  j["ldr"]["weight_average"] = {{"decay", 0.99}};
  EXPECT_DOUBLE_EQ(ExperimentConfig::from_json(j, "test.json").ldr_training.weight_average.decay,
                   0.99);
  EXPECT_DOUBLE_EQ(c.ldr_training.weight_average.decay, 0.0) << "off when absent";
  // one classifier over every regime (an extension, off when absent): {"observational": bool}
  j = c.raw;
  j["ldr"]["all_regimes"] = true;
  EXPECT_NE(error_of(j).find("config.ldr.all_regimes: expected an object {\"observational\"}, "
                             "got a boolean"),
            std::string::npos)
      << error_of(j);
  j["ldr"]["all_regimes"] = {{"observational", "yes"}};
  EXPECT_NE(error_of(j).find("config.ldr.all_regimes.observational: expected true or false, got "
                             "\"yes\""),
            std::string::npos)
      << error_of(j);
  j["ldr"]["all_regimes"] = nlohmann::json::object();
  j["ldr"]["members"] = 3;
  EXPECT_NE(error_of(j).find("config.ldr.all_regimes: one classifier over every regime, not with "
                             "config.ldr.members 3"),
            std::string::npos)
      << error_of(j);
  j["ldr"].erase("members");
  EXPECT_TRUE(ExperimentConfig::from_json(j, "test.json").ldr_training.all_regimes.on);
  EXPECT_TRUE(ExperimentConfig::from_json(j, "test.json").ldr_training.all_regimes.observational);
  j["ldr"]["all_regimes"] = {{"observational", false}};
  EXPECT_FALSE(ExperimentConfig::from_json(j, "test.json").ldr_training.all_regimes.observational);
  EXPECT_FALSE(c.ldr_training.all_regimes.on) << "off when absent";
  // AE2's logit term (an extension, off when absent): {"weight" > 0}
  j = c.raw;
  j["ae2"]["logit_loss"] = {{"weight", -1}};
  EXPECT_NE(error_of(j).find("config.ae2.logit_loss.weight: expected in (0, 1e6], got -1"),
            std::string::npos)
      << error_of(j);
  j["ae2"]["logit_loss"] = {{"weight", 0.5}, {"target", 1}};
  EXPECT_NE(error_of(j).find("config.ae2.logit_loss.target: unknown key"), std::string::npos)
      << error_of(j);
  j["ae2"]["logit_loss"] = {{"weight", 0.5}};
  EXPECT_DOUBLE_EQ(ExperimentConfig::from_json(j, "test.json").ae2_training.logit_loss.weight, 0.5);
  EXPECT_DOUBLE_EQ(c.ae2_training.logit_loss.weight, 0.0) << "off when absent";
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
  } catch (const ropes::core::ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("'no-such-config' is neither a file nor an installed"),
              std::string::npos);
  }
}

// AE1's occlusion augmentation: every image of a batch of black images, at probability 1,
// carries exactly one white square of a side within the bounds; at probability 1/2 about half
// do; a step's squares are the same when drawn again and differ from another step's; the
// input is not touched.
TEST(OcclusionAugmentation, PaintsOneSquareAnImageAtTheProbabilityAndTheSameOnesAgain) {
  const std::int64_t n = 400, side = 32;
  const nn::Tensor black(nn::Shape{n, 1, side, side},
                         nn::Buffer(static_cast<std::size_t>(n * side * side), 0.0f));
  OcclusionAugmentation a{1.0, 4, 12};
  const nn::Tensor all = occlusion_augmented(black, a, 7, 3);
  const std::vector<float> v = all.to_vector();
  for (std::int64_t i = 0; i < n; ++i) {
    std::int64_t lit = 0, top = side, bottom = -1, left = side, right = -1;
    for (std::int64_t r = 0; r < side; ++r)
      for (std::int64_t c = 0; c < side; ++c)
        if (v[static_cast<std::size_t>((i * side + r) * side + c)] == 1.0f) {
          ++lit;
          top = std::min(top, r);
          bottom = std::max(bottom, r);
          left = std::min(left, c);
          right = std::max(right, c);
        }
    const std::int64_t h = bottom - top + 1, w = right - left + 1;
    ASSERT_EQ(h, w) << "image " << i;
    ASSERT_EQ(lit, h * w) << "image " << i << ": one filled square";
    ASSERT_GE(h, 4);
    ASSERT_LE(h, 12);
  }
  EXPECT_EQ(black.to_vector(), std::vector<float>(v.size(), 0.0f)) << "the input was changed";
  EXPECT_EQ(occlusion_augmented(black, a, 7, 3).to_vector(), v);
  EXPECT_NE(occlusion_augmented(black, a, 7, 4).to_vector(), v);
  a.probability = 0.5;
  const std::vector<float> half = occlusion_augmented(black, a, 7, 3).to_vector();
  std::int64_t painted = 0;
  for (std::int64_t i = 0; i < n; ++i)
    painted += std::any_of(half.begin() + i * side * side, half.begin() + (i + 1) * side * side,
                           [](float x) { return x != 0.0f; });
  // binomial(400, 1/2): mean 200, standard deviation 10; 5 of them either way
  EXPECT_NEAR(static_cast<double>(painted), 200.0, 50.0);
  a.max_size = 33;
  EXPECT_THROW(occlusion_augmented(black, a, 7, 3), std::invalid_argument);
}

// With the difference loss a pair is occluded together: occlusion_augmented reports exactly
// the images it painted (read back from black images), occlusion_augmented_where paints those
// and no other, each with a square of its own (its side and place from its own stream), and
// a `squared` of another length is refused.
TEST(OcclusionAugmentation, APairIsOccludedTogether) {
  const std::int64_t n = 200, side = 32;
  const nn::Tensor black(nn::Shape{n, 1, side, side},
                         nn::Buffer(static_cast<std::size_t>(n * side * side), 0.0f));
  const OcclusionAugmentation a{0.5, 4, 12};
  auto painted = [&](const std::vector<float>& v, std::int64_t i) {
    return std::any_of(v.begin() + i * side * side, v.begin() + (i + 1) * side * side,
                       [](float x) { return x != 0.0f; });
  };
  std::vector<char> squared;
  const std::vector<float> samples = occlusion_augmented(black, a, 7, 3, &squared).to_vector();
  ASSERT_EQ(squared.size(), static_cast<std::size_t>(n));
  EXPECT_EQ(samples, occlusion_augmented(black, a, 7, 3).to_vector()) << "reporting changed it";
  const std::vector<float> partners =
      occlusion_augmented_where(black, squared, a, 8, 3).to_vector();
  std::int64_t count = 0, same_place = 0;
  for (std::int64_t i = 0; i < n; ++i) {
    const bool s = squared[static_cast<std::size_t>(i)] != 0;
    count += s;
    EXPECT_EQ(painted(samples, i), s) << "image " << i;
    EXPECT_EQ(painted(partners, i), s) << "partner " << i;
    same_place +=
        s && std::equal(samples.begin() + i * side * side, samples.begin() + (i + 1) * side * side,
                        partners.begin() + i * side * side);
  }
  EXPECT_GT(count, 0);
  EXPECT_LT(count, n);
  EXPECT_LT(same_place, count / 4) << "the partners' squares are drawn from a stream of their own";
  EXPECT_EQ(occlusion_augmented_where(black, squared, a, 8, 3).to_vector(), partners);
  squared.pop_back();
  EXPECT_THROW(occlusion_augmented_where(black, squared, a, 8, 3), std::invalid_argument);
}

// AE1's difference loss on three hand-made pairs of 1x1x2 images, each value worked out by hand:
//   pair 0: reconstruction (0.25^2 / 2 + 0.5^2 / 2) / 2 = 0.078125; change [0.5, 0] (its
//           squared size 0.25 is raised to the floor 1); change error [0.25, -0.5] - [0.5, 0]
//           = [-0.25, -0.5], squared 0.3125; with weight 2: 0.078125 + 0.625 = 0.703125
//   pair 1: the image is its own observational one (mask 0): only the reconstruction,
//           (0.5^2 / 2 + 0.5^2 / 2) / 2 = 0.125
//   pair 2: reconstruction (0.5^2 / 2 + 0) / 2 = 0.0625; change [1, 1] (squared size 2);
//           change error [1, 0.5] - [1, 1] = [0, -0.5], squared 0.25; 2 * 0.25 / 2 = 0.25;
//           0.3125
// and its gradient with respect to both reconstructions against central differences.
TEST(Ae1DifferenceLoss, MatchesTheHandWorkedValuesAndFiniteDifferences) {
  const nn::Shape shape{3, 1, 1, 2};
  auto tensor = [](const nn::Shape& s, std::vector<float> v) {
    return nn::Tensor(s, nn::Buffer(v.begin(), v.end()));
  };
  const nn::Tensor x = tensor(shape, {0.5f, 0.0f, 1.0f, 1.0f, 1.0f, 1.0f});
  const nn::Tensor xo = tensor(shape, {0.0f, 0.0f, 1.0f, 1.0f, 0.0f, 0.0f});
  const nn::Tensor recon = tensor(shape, {0.25f, 0.0f, 1.0f, 0.5f, 1.0f, 0.5f});
  const nn::Tensor recon_o = tensor(shape, {0.0f, 0.5f, 1.0f, 0.5f, 0.0f, 0.0f});
  const nn::Tensor mask = tensor(nn::Shape{3}, {1.0f, 0.0f, 1.0f});
  const std::vector<float> v = ae1_difference_loss(recon, recon_o, x, xo, mask, 2.0).to_vector();
  ASSERT_EQ(v.size(), 3u);
  EXPECT_FLOAT_EQ(v[0], 0.703125f);
  EXPECT_FLOAT_EQ(v[1], 0.125f);
  EXPECT_FLOAT_EQ(v[2], 0.3125f);
  const nn::GradCheckResult g = nn::check_gradients(
      [&](const std::vector<nn::Tensor>& in) {
        return ae1_difference_loss(in[0], in[1], x, xo, mask, 2.0);
      },
      {recon, recon_o});
  EXPECT_TRUE(g.ok) << g.report;
  try {
    ae1_difference_loss(recon, recon_o, x, xo, tensor(nn::Shape{2}, {1.0f, 1.0f}), 2.0);
    FAIL() << "a mask of another length was accepted";
  } catch (const std::invalid_argument& e) {
    EXPECT_NE(std::string(e.what()).find("mask [2]"), std::string::npos) << e.what();
  }
}
