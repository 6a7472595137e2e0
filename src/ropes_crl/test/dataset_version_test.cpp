#include "ropes_crl/dataset_version.hpp"

#include <gtest/gtest.h>

#include <ropes_core/npy.hpp>

#include <unistd.h>
#include <filesystem>
#include <string>

namespace fs = std::filesystem;

namespace {

// a one-column dataset whose metadata is `metadata`
ropes::core::DatasetReader dataset_with(const std::string& name, const std::string& metadata) {
  const fs::path dir =
      fs::temp_directory_path() / ("ropes_crl_version_" + name + std::to_string(::getpid()));
  fs::remove_all(dir);
  const std::vector<ropes::core::ColumnSpec> columns = {{"regime", ropes::core::DType::kI32, {}}};
  ropes::core::NpyArray regime;
  regime.dtype = ropes::core::DType::kI32;
  regime.shape = {2};
  regime.data.assign(8, 0);
  ropes::core::write_dataset_shard(dir, 0, columns, {regime});
  ropes::core::write_dataset_manifest(dir, columns, 1, metadata);
  return ropes::core::DatasetReader::open(dir);
}

std::string refusal(const ropes::core::DatasetReader& reader) {
  try {
    ropes::crl::require_current_sim_dataset(reader);
  } catch (const ropes::core::FileFormatError& e) {
    return e.what();
  }
  return "";
}

}  // namespace

// sim_dataset_version 2 read the paper's TN(mean, x) as a standard deviation: refused, naming
// the manifest, the version and what to do; 3 and a dataset not made by ropes-generate pass
TEST(SimDatasetVersion, RefusesTheOldStandardDeviationReading) {
  const auto old = dataset_with("old", R"({"sim_dataset_version": 2})");
  const std::string message = refusal(old);
  EXPECT_NE(message.find((old.dir() / "manifest.json").string() +
                         ": sim_dataset_version 2, made when ropes-generate read the paper's "
                         "TN(mean, x) as a standard deviation"),
            std::string::npos)
      << message;
  EXPECT_NE(message.find("generate the dataset again"), std::string::npos) << message;
  EXPECT_NE(refusal(dataset_with("bad", R"({"sim_dataset_version": "3"})"))
                .find("metadata.sim_dataset_version is not an integer (string)"),
            std::string::npos);
  EXPECT_EQ(refusal(dataset_with("current", R"({"sim_dataset_version": 3})")), "");
  EXPECT_EQ(refusal(dataset_with("own", R"({"cameras": ["mine"]})")), "");
  for (const char* name : {"old", "bad", "current", "own"})
    fs::remove_all(fs::temp_directory_path() /
                   ("ropes_crl_version_" + std::string(name) + std::to_string(::getpid())));
}
