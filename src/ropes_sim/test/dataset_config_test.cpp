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
