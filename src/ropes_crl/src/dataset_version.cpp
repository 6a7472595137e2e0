#include "ropes_crl/dataset_version.hpp"

#include <nlohmann/json.hpp>

#include <cstdint>
#include <filesystem>
#include <string>

#include <ropes_core/file_format_error.hpp>
#include <ropes_core/file_io.hpp>
#include <ropes_core/json_text.hpp>

#include "ropes_crl/run_directory.hpp"

namespace ropes::crl {

namespace {

// the metadata's sim_dataset_version checked: FileFormatError naming `manifest` when it is
// not an integer or is older than the oldest version read
void check_version(const nlohmann::json& meta, const std::string& manifest,
                   const std::string& dataset_dir) {
  if (!meta.is_object() || !meta.contains("sim_dataset_version"))
    return;
  const nlohmann::json& v = meta["sim_dataset_version"];
  if (!v.is_number_integer())
    throw core::FileFormatError(manifest + ": metadata.sim_dataset_version is not an integer (" +
                                std::string(v.type_name()) + ")");
  const auto version = v.get<std::int64_t>();
  if (version < kOldestSimDatasetVersion)
    throw core::FileFormatError(
        manifest + ": sim_dataset_version " + std::to_string(version) +
        ", made when ropes-generate read the paper's TN(mean, x) as a standard deviation; the "
        "paper's x is a variance (sim_dataset_version " +
        std::to_string(kOldestSimDatasetVersion) +
        "), so these are not the paper's distributions: generate the dataset again with this "
        "ropes-generate (into a new directory, or remove " +
        dataset_dir + " first)");
}

// the JSON in `path`, or a discarded value when it is missing, over `limit` bytes or not JSON
nlohmann::json json_if_readable(const std::filesystem::path& path, std::uint64_t limit) {
  try {
    return core::read_json_file_if_present(path, limit);
  } catch (const core::FileFormatError&) {
    return nlohmann::json(nlohmann::json::value_t::discarded);
  }
}

}  // namespace

void require_current_sim_dataset(const core::DatasetReader& reader) {
  check_version(reader.metadata(), (reader.dir() / "manifest.json").string(),
                reader.dir().string());
}

void require_run_of_current_sim_dataset(const std::filesystem::path& run_dir) {
  if (!core::is_regular_file(run_dir / "run.json"))
    return;
  require_run_of_current_sim_dataset(RunDirectory::open(run_dir));
}

void require_run_of_current_sim_dataset(const RunDirectory& run) {
  const std::filesystem::path& data_dir = run.data_dir();
  const nlohmann::json manifest =
      json_if_readable(data_dir / "manifest.json", core::kMaxManifestBytes);
  if (!manifest.is_object() || !manifest.contains("metadata"))
    return;
  try {
    check_version(manifest["metadata"], (data_dir / "manifest.json").string(), data_dir.string());
  } catch (const core::FileFormatError& e) {
    throw core::FileFormatError(run.run_file().string() +
                                ": the run was trained on an outdated dataset: " + e.what() +
                                ", and train the run again on it");
  }
}

}  // namespace ropes::crl
