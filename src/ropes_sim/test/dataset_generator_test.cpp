#include "ropes_sim/dataset_generator.hpp"

#include <gtest/gtest.h>
#include <nlohmann/json.hpp>

#include <cstring>
#include <fstream>
#include <sstream>

#include "ropes_core/dataset.hpp"
#include "ropes_sim/intervention_sampler.hpp"
#include "ropes_sim/kinematics.hpp"
#include "ropes_sim/renderer.hpp"

namespace ropes::sim {
namespace {

namespace fs = std::filesystem;

fs::path temp_dir(const std::string& name) {
  const fs::path dir = fs::temp_directory_path() / ("ropes_sim_gen_" + name);
  fs::remove_all(dir);
  fs::create_directories(dir);
  return dir;
}

// a small 2C-like config: 5 anchors of 13 samples, 2 shards of 3 anchors, 40x32 images
fs::path write_config(const fs::path& dir, const std::string& rig = "\"two_cameras\"",
                      const std::string& distribution = "2c_independent.json") {
  const fs::path path = dir / "tiny.json";
  std::ofstream(path) << R"({"name": "tiny", "distribution": ")"
                      << (fs::path(ROPES_SIM_DISTRIBUTIONS_DIR) / distribution).string()
                      << R"(", "robot": ")"
                      << (fs::path(ROPES_SIM_URDF_DIR) / "panda.urdf").string() << R"(", "rig": )"
                      << rig << R"(, "image": {"width": 40, "height": 32}, "anchors": 5,
                          "anchors_per_shard": 3})";
  return path;
}

// every file under `dir`, relative path -> bytes
std::map<std::string, std::string> files(const fs::path& dir) {
  std::map<std::string, std::string> out;
  for (const auto& e : fs::recursive_directory_iterator(dir)) {
    if (!e.is_regular_file())
      continue;
    std::ifstream in(e.path(), std::ios::binary);
    std::ostringstream s;
    s << in.rdbuf();
    out[fs::relative(e.path(), dir).string()] = s.str();
  }
  return out;
}

GenerateOptions options(const fs::path& out, int threads, int k = 0, int n = 1) {
  GenerateOptions o;
  o.out = out;
  o.seed = 11;
  o.threads = threads;
  o.shard_index = k;
  o.shard_count = n;
  return o;
}

TEST(DatasetGenerator, SameBytesForAnyThreadCountAndSharding) {
  const fs::path dir = temp_dir("same");
  const auto config = DatasetConfig::load(write_config(dir));
  const auto one = generate_dataset(config, options(dir / "t1", 1));
  EXPECT_TRUE(one.complete);
  EXPECT_EQ(one.shards_written, 2);
  EXPECT_EQ(one.images, 5 * 13 * 2);
  generate_dataset(config, options(dir / "t2", 2));
  // two shard runs into one directory; the second finds both shards and writes the manifest
  EXPECT_FALSE(generate_dataset(config, options(dir / "s", 1, 1, 2)).complete);
  EXPECT_FALSE(fs::exists(dir / "s" / "manifest.json"));
  EXPECT_TRUE(generate_dataset(config, options(dir / "s", 2, 0, 2)).complete);
  const auto reference = files(dir / "t1");
  EXPECT_EQ(reference.size(), 2u * 5u + 2u);  // 4 columns + marker per shard, manifest, generation
  EXPECT_EQ(files(dir / "t2"), reference);
  EXPECT_EQ(files(dir / "s"), reference);
  // run again: nothing to do, nothing changed
  const auto again = generate_dataset(config, options(dir / "t1", 2));
  EXPECT_TRUE(again.complete);
  EXPECT_EQ(again.shards_written, 0);
  EXPECT_EQ(files(dir / "t1"), reference);
}

TEST(DatasetGenerator, RowsHoldWhatTheSamplerAndRendererGive) {
  const fs::path dir = temp_dir("rows");
  const auto config = DatasetConfig::load(write_config(dir));
  generate_dataset(config, options(dir / "d", 2));
  const auto reader = core::DatasetReader::open(dir / "d");
  ASSERT_EQ(reader.rows(), 5 * 13);
  EXPECT_EQ(reader.column("images").row_shape, (std::vector<std::int64_t>{2, 32, 40}));
  const auto meta = nlohmann::json::parse(reader.metadata_json());
  EXPECT_EQ(meta["seed"], 11);
  EXPECT_EQ(meta["cameras"], (std::vector<std::string>{"yaw45", "yaw135"}));
  EXPECT_EQ(meta["regime_names"].size(), 13u);
  EXPECT_EQ(meta["joint_names"][0], "panda_joint1");
  // every regime parsed: the joint it intervenes on and which intervention
  EXPECT_EQ(meta["sim_dataset_version"], 3);
  ASSERT_EQ(meta["regimes"].size(), 13u);
  EXPECT_EQ(meta["regimes"][0], nlohmann::json::parse(R"({"name": "observational", "joint": null,
                                   "joint_index": null, "intervention": null})"));
  EXPECT_EQ(meta["regimes"][5], nlohmann::json::parse(R"({"name": "do(panda_joint3)=1",
                                   "joint": "panda_joint3", "joint_index": 2, "intervention": 1})"));
  EXPECT_EQ(meta["regimes"][12]["joint"], "panda_joint6");
  EXPECT_EQ(meta["regimes"][12]["intervention"], 2);

  // row 4 * 13 + 5 = anchor 4 (second shard), regime 5: do(joint 3)=1
  const auto sampler = InterventionSampler::load(config.distribution);
  const auto q = sampler.sample_anchor(11, 4)[5];
  const std::int64_t row = 4 * 13 + 5;
  const auto angles = reader.read_rows("angles", row, 1);
  for (int j = 0; j < 7; ++j)
    EXPECT_EQ(reinterpret_cast<const float*>(angles.data.data())[j], static_cast<float>(q[j]));
  std::int32_t regime = -1;
  std::int64_t anchor = -1;
  reader.read_rows("regime", row, 1, &regime);
  reader.read_rows("anchor", row, 1, &anchor);
  EXPECT_EQ(regime, 5);
  EXPECT_EQ(anchor, 4);
  // the image is what the renderer draws for that configuration
  const auto model = RobotModel::load(config.robot);
  Kinematics kinematics(model);
  kinematics.set_positions(q);
  Renderer renderer(Scene::build(model), 40, 32);
  const auto expected = renderer.render(kinematics.link_poses(), config.rig.cameras[1]);
  const auto images = reader.read_rows("images", row, 1);
  EXPECT_EQ(0, std::memcmp(images.data.data() + 40 * 32, expected.data(), expected.size()));
  reader.verify();
}

// a dataset of sim_dataset_version 1 (before "regimes"): it opens and reads as before; a
// reader that needs the regimes gets an error that names the field and the manifest
TEST(DatasetGenerator, ADatasetWithoutRegimeMetadataStillOpens) {
  const fs::path dir = temp_dir("old");
  generate_dataset(DatasetConfig::load(write_config(dir)), options(dir / "d", 2));
  const fs::path manifest = dir / "d" / "manifest.json";
  nlohmann::json m = nlohmann::json::parse(std::ifstream(manifest));
  m["metadata"].erase("regimes");
  m["metadata"]["sim_dataset_version"] = 1;
  std::ofstream(manifest) << m.dump(2) << "\n";
  const auto reader = core::DatasetReader::open(dir / "d");
  EXPECT_EQ(reader.rows(), 5 * 13);
  EXPECT_EQ(reader.metadata_at("/regime_names/5").get<std::string>(), "do(panda_joint3)=1");
  try {
    reader.metadata_at("/regimes", "sim_dataset_version 1; regenerate it with ropes-generate");
    ADD_FAILURE() << "an old dataset had regimes";
  } catch (const core::FileFormatError& e) {
    EXPECT_NE(std::string(e.what()).find(manifest.string() + ": metadata has no /regimes "
                                                             "(sim_dataset_version 1; "),
              std::string::npos)
        << e.what();
  }
  reader.verify();  // the shards are untouched
}

// a dataset or an unfinished one of sim_dataset_version 2, which read the paper's TN(mean, x)
// as a standard deviation: generate_dataset neither reuses nor resumes it, says why and what
// to do, and leaves it as it was
TEST(DatasetGenerator, RefusesADatasetOfTheOldStandardDeviationReading) {
  const fs::path dir = temp_dir("old_reading");
  const auto config = DatasetConfig::load(write_config(dir));
  generate_dataset(config, options(dir / "d", 1));
  generate_dataset(config, options(dir / "u", 1, 1, 2));  // unfinished: generation.json only
  for (const fs::path& file : {dir / "d" / "manifest.json", dir / "u" / kGenerationFile}) {
    nlohmann::json m = nlohmann::json::parse(std::ifstream(file));
    nlohmann::json& meta = file.filename() == "manifest.json" ? m["metadata"] : m;
    meta["sim_dataset_version"] = 2;
    std::ofstream(file) << m.dump(2) << "\n";
    const fs::path out = file.parent_path();
    const auto before = files(out);
    try {
      generate_dataset(config, options(out, 1));
      ADD_FAILURE() << file << ": a version 2 dataset was accepted";
    } catch (const std::runtime_error& e) {
      const std::string what = e.what();
      EXPECT_NE(what.find(file.string() + ": sim_dataset_version 2, made when ropes-generate "
                                          "read the paper's TN(mean, x) as a standard deviation"),
                std::string::npos)
          << what;
      EXPECT_NE(what.find("remove " + out.string() + " and generate it again"), std::string::npos)
          << what;
    }
    EXPECT_EQ(files(out), before) << file;
  }
}

TEST(DatasetGenerator, RefusesADirectoryHoldingSomethingElse) {
  const fs::path dir = temp_dir("refuse");
  const auto config = DatasetConfig::load(write_config(dir));
  generate_dataset(config, options(dir / "d", 1));
  const auto before = files(dir / "d");
  auto other = options(dir / "d", 1);
  other.seed = 12;
  try {
    generate_dataset(config, other);
    FAIL() << "a different seed was accepted";
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("holds a different dataset (manifest.json: /seed: 12 now, "
                                         "11 there)"),
              std::string::npos)
        << e.what();
  }
  EXPECT_EQ(files(dir / "d"), before);
  // an unfinished one: only shard 1 of 2 written
  generate_dataset(config, options(dir / "u", 1, 1, 2));
  EXPECT_THROW(generate_dataset(config, other), std::runtime_error);
  // a directory with someone's files
  fs::create_directories(dir / "mine");
  std::ofstream(dir / "mine" / "thesis.tex") << "precious";
  try {
    generate_dataset(config, options(dir / "mine", 1));
    FAIL();
  } catch (const std::runtime_error& e) {
    EXPECT_NE(std::string(e.what()).find("is not empty and holds no ropes dataset"),
              std::string::npos);
  }
  EXPECT_EQ(files(dir / "mine").size(), 1u);
}

TEST(DatasetGenerator, ACameraLookingAtNothingIsAConfigError) {
  const fs::path dir = temp_dir("nothing");
  const auto config = DatasetConfig::load(
      write_config(dir, R"({"name": "away", "cameras": [{"name": "sky", "target": [0, 0, 30]}]})"));
  try {
    generate_dataset(config, options(dir / "d", 1));
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("rig camera 'sky'"), std::string::npos) << e.what();
    EXPECT_NE(std::string(e.what()).find("looks at nothing"), std::string::npos);
  }
  EXPECT_FALSE(fs::exists(dir / "d"));  // found before the directory was touched
}

TEST(DatasetGenerator, AShardOfAnotherDatasetCopiedInIsRedoneNotMixed) {
  const fs::path dir = temp_dir("mixed");
  const auto config = DatasetConfig::load(write_config(dir));
  generate_dataset(config, options(dir / "ref", 2));
  auto other = options(dir / "other", 1);
  other.seed = 12;
  generate_dataset(config, other);
  // shard 0 of seed 11 here, then shard 1 of seed 12 copied in as if merged by hand
  EXPECT_FALSE(generate_dataset(config, options(dir / "merged", 1, 0, 2)).complete);
  for (const char* f : {"images-00001.npy", "angles-00001.npy", "regime-00001.npy",
                        "anchor-00001.npy", "00001.json"})
    fs::copy_file(dir / "other" / "shards" / f, dir / "merged" / "shards" / f);
  const auto merged = generate_dataset(config, options(dir / "merged", 1));
  EXPECT_TRUE(merged.complete);
  EXPECT_EQ(merged.shards_written, 1);  // the foreign shard, redone
  EXPECT_EQ(files(dir / "merged"), files(dir / "ref"));
}

TEST(DatasetGenerator, ShardsTooManyOrTooLargeAreConfigErrors) {
  const fs::path dir = temp_dir("sizes");
  auto config = DatasetConfig::load(write_config(dir));
  const auto message = [&] {
    try {
      generate_dataset(config, options(dir / "d", 1));
    } catch (const ConfigError& e) {
      return std::string(e.what());
    }
    return std::string("no error");
  };
  config.anchors_per_shard = 1 << 20;  // 13 x 2 x 40 x 32 bytes each: 32 GiB a shard
  EXPECT_NE(message().find("anchors_per_shard 1048576 makes image shards of 32.5"),
            std::string::npos)
      << message();
  config.anchors = 1LL << 40;
  config.anchors_per_shard = 1;
  EXPECT_NE(message().find("shards; expected at most 16777216"), std::string::npos) << message();
  EXPECT_FALSE(fs::exists(dir / "d"));
}

TEST(DatasetGenerator, AJointTheRobotDoesNotHaveIsNamed) {
  const fs::path dir = temp_dir("joint");
  std::ifstream in(fs::path(ROPES_SIM_DISTRIBUTIONS_DIR) / "1c_independent.json");
  std::stringstream s;
  s << in.rdbuf();
  std::string text = s.str();
  for (std::size_t at; (at = text.find("panda_joint7")) != std::string::npos;)
    text.replace(at, 12, "wrist_joint9");
  std::ofstream(dir / "odd.json") << text;
  const auto config =
      DatasetConfig::load(write_config(dir, "\"single_camera\"", (dir / "odd.json").string()));
  try {
    generate_dataset(config, options(dir / "d", 1));
    FAIL();
  } catch (const ConfigError& e) {
    EXPECT_NE(std::string(e.what()).find("joint 'wrist_joint9' is not a movable joint of robot "
                                         "'ropes_panda'"),
              std::string::npos)
        << e.what();
  }
}

}  // namespace
}  // namespace ropes::sim
