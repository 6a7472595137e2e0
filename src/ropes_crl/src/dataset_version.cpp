#include "ropes_crl/dataset_version.hpp"

#include <nlohmann/json.hpp>

#include <string>

#include <ropes_nn/npy.hpp>

namespace ropes::crl {

void require_current_sim_dataset(const nn::DatasetReader& reader) {
  const nlohmann::json& meta = reader.metadata();
  if (!meta.is_object() || !meta.contains("sim_dataset_version"))
    return;
  const std::string manifest = (reader.dir() / "manifest.json").string();
  const nlohmann::json& v = meta["sim_dataset_version"];
  if (!v.is_number_integer())
    throw nn::FileFormatError(manifest + ": metadata.sim_dataset_version is not an integer (" +
                              std::string(v.type_name()) + ")");
  const auto version = v.get<std::int64_t>();
  if (version < kOldestSimDatasetVersion)
    throw nn::FileFormatError(
        manifest + ": sim_dataset_version " + std::to_string(version) +
        ", made when ropes-generate read the paper's TN(mean, x) as a standard deviation; the "
        "paper's x is a variance (sim_dataset_version " +
        std::to_string(kOldestSimDatasetVersion) +
        "), so these are not the paper's distributions: generate the dataset again with this "
        "ropes-generate (into a new directory, or remove " +
        reader.dir().string() + " first)");
}

}  // namespace ropes::crl
