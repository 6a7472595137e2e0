#include "ropes_sim/dataset_config.hpp"

#include <gtest/gtest.h>

#include <filesystem>
#include <fstream>
#include <sstream>

#include "ropes_sim/intervention_sampler.hpp"

namespace ropes::sim {
namespace {

namespace fs = std::filesystem;

const std::string kGood = std::string(R"({"name": "tiny", "distribution": ")") +
                          (fs::path(ROPES_SIM_DISTRIBUTIONS_DIR) / "2c_independent.json").string() +
                          R"(", "robot": ")" +
                          (fs::path(ROPES_SIM_URDF_DIR) / "panda.urdf").string() +
                          R"(", "rig": "two_cameras", "image": {"width": 40, "height": 32},
                          "anchors": 5, "anchors_per_shard": 3})";

TEST(DatasetConfig, InstalledConfigsLoad) {
  for (const char* name : {"1c", "2c", "2c_causal", "2c_ood", "small-1c"}) {
    const auto c =
        DatasetConfig::load(fs::path(ROPES_SIM_DATASETS_DIR) / (std::string(name) + ".json"));
    EXPECT_EQ(c.name, name);
    EXPECT_EQ(c.rig.width, 128);
    EXPECT_EQ(c.rig.cameras.size(), std::string(name).find("2c") == 0 ? 2u : 1u);
  }
}

// every installed config's test sets (the suites' ood and causal test sets, and a smaller id
// test set where one is named) are installed configs of the same rig and image size; a 2C
// training config names ood and causal, a 1C one none; an id test set has the training
// config's own distribution
TEST(DatasetConfig, InstalledTestSetsExistAndShowTheRobotAsTheTrainingSetDoes) {
  int named = 0;
  for (const auto& entry : fs::directory_iterator(ROPES_SIM_DATASETS_DIR)) {
    const auto c = DatasetConfig::load(entry.path());
    const bool two_camera_training =
        c.name.find("2c") != std::string::npos && c.name.find("_ood") == std::string::npos;
    const bool plus = c.name.rfind("small-plus-", 0) == 0;
    EXPECT_EQ(c.test_sets.size(), two_camera_training ? (plus ? 3u : 2u) : 0u) << c.name;
    for (const auto& [suite, name] : c.test_sets) {
      const auto t = DatasetConfig::load(fs::path(ROPES_SIM_DATASETS_DIR) / (name + ".json"));
      EXPECT_EQ(t.rig.cameras.size(), c.rig.cameras.size()) << c.name << " " << suite;
      EXPECT_EQ(t.rig.width, c.rig.width) << c.name << " " << suite;
      EXPECT_TRUE(t.test_sets.empty() || suite != "ood") << name;
      if (suite == "id") {
        EXPECT_EQ(t.distribution, c.distribution) << c.name;
        EXPECT_LT(t.anchors, c.anchors) << c.name;
      }
      ++named;
    }
  }
  // tiny, small and paper: 2c and 2c_causal, each ood and causal; small-plus also id
  EXPECT_EQ(named, 18);
  EXPECT_EQ(
      DatasetConfig::load(fs::path(ROPES_SIM_DATASETS_DIR) / "small-2c.json").test_sets.at("ood"),
      "small-2c_ood");
  EXPECT_EQ(DatasetConfig::load(fs::path(ROPES_SIM_DATASETS_DIR) / "small-plus-2c.json")
                .test_sets.at("id"),
            "small-2c");
}

TEST(DatasetConfig, BadFieldsAreNamed) {
  const fs::path dir = fs::temp_directory_path() / "ropes_sim_config_test";
  fs::create_directories(dir);
  const auto message = [&](const std::string& text) {
    std::ofstream(dir / "c.json") << text;
    try {
      DatasetConfig::load(dir / "c.json");
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  const std::string good = kGood;
  EXPECT_EQ(message(good), "no error");
  const auto with = [&](const std::string& from, const std::string& to) {
    std::string t = good;
    const auto at = t.find(from);
    EXPECT_NE(at, std::string::npos) << from;
    return message(t.replace(at, from.size(), to));
  };
  EXPECT_NE(with("\"anchors\": 5", "\"anchors\": 0").find("anchors is 0; expected an integer"),
            std::string::npos);
  EXPECT_NE(with("\"anchors\": 5", "\"ancors\": 5").find("unknown field 'ancors'"),
            std::string::npos);
  EXPECT_NE(with("\"width\": 40", "\"width\": 4").find("image.width is 4"), std::string::npos);
  EXPECT_NE(with("\"two_cameras\"", "\"three_cameras\"").find("rig is \"three_cameras\""),
            std::string::npos);
  EXPECT_NE(with("panda.urdf", "nope.urdf").find("nope.urdf does not exist"), std::string::npos);
  EXPECT_NE(with("\"two_cameras\"", R"({"name": "r", "cameras": [{"name": "c", "fov_y_deg": 0}]})")
                .find("rig.cameras[0]: camera 'c': fov_y_deg = 0"),
            std::string::npos);
  EXPECT_NE(message("{\"name\": ").find("not JSON"), std::string::npos);
  // test_sets: an object of id, ood and causal, each the plain name of a config
  const std::string sets = "\"anchors_per_shard\": 3";
  EXPECT_EQ(with(sets, sets + R"(, "test_sets": {"ood": "small-2c_ood"})"), "no error");
  EXPECT_EQ(with(sets, sets + R"(, "test_sets": {"id": "small-2c"})"), "no error");
  EXPECT_NE(with(sets, sets + R"(, "test_sets": ["ood"])")
                .find("test_sets is a JSON array; expected an object of suites"),
            std::string::npos);
  EXPECT_NE(with(sets, sets + R"(, "test_sets": {"occlusion": "x"})")
                .find("test_sets has the suite 'occlusion'; expected id, ood or causal"),
            std::string::npos);
  EXPECT_NE(with(sets, sets + R"(, "test_sets": {"ood": "../x"})")
                .find("test_sets.ood is '../x'; expected the name of an installed dataset config"),
            std::string::npos);
  EXPECT_NE(with(sets, sets + R"(, "test_sets": {"causal": 3})").find("test_sets.causal"),
            std::string::npos);
  // a name is never a path (ropes-eval names its test-set cache directories after it)
  for (const char* name : {"../../tmp/x", "/etc/x", ".hidden", "a/b"}) {
    EXPECT_NE(with("\"name\": \"tiny\"", std::string("\"name\": \"") + name + "\"")
                  .find("name is '" + std::string(name) + "'; expected a plain name"),
              std::string::npos)
        << name;
  }
  // a config file of 2 GiB (sparse) is refused by its size, before it is read
  std::ofstream(dir / "c.json") << "{";
  fs::resize_file(dir / "c.json", std::uint64_t{2} << 30);
  try {
    DatasetConfig::load(dir / "c.json");
    ADD_FAILURE() << "a 2 GiB config loaded";
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("holds 2147483648 bytes; expected at most 16777216"),
              std::string::npos)
        << e.what();
  }
  fs::remove(dir / "c.json");
}

}  // namespace
}  // namespace ropes::sim
