#pragma once
/// @file dataset_version.hpp
/// require_current_sim_dataset: refuses a dataset that ropes-generate made before its
/// distribution numbers meant what the paper's do.
///
/// Up to sim_dataset_version 2, ropes_sim read the second parameter of the paper's
/// TN_[a,b](mu, x) as a standard deviation; the paper defines it as a variance (its line 472),
/// so those datasets are not the paper's (for example the 2C angles have variance 0.16, not
/// the paper's 0.35). Version 3 reads it as the paper does. ropes_crl does not link the
/// simulator; it reads the version from the manifest's metadata.
#include <ropes_core/dataset.hpp>

#include <filesystem>

namespace ropes::crl {

class RunDirectory;  // run_directory.hpp

/// The oldest sim_dataset_version (manifest metadata) that ropes-train and ropes-eval accept.
inline constexpr int kOldestSimDatasetVersion = 3;

/// Throws core::FileFormatError naming DIR/manifest.json, the version found and what to do
/// (generate the dataset again) when the metadata holds a sim_dataset_version below
/// kOldestSimDatasetVersion, or one that is not an integer. A dataset without the field
/// (not made by ropes-generate: a user's own images) passes. Cost: a look-up in the metadata.
void require_current_sim_dataset(const core::DatasetReader& reader);

/// The same for the training set of the run in `run_dir`: throws core::FileFormatError naming
/// RUN/run.json, the training set's manifest, the version and what to do (generate the
/// dataset again and train the run again) when the manifest run.json's data_dir points to
/// holds a sim_dataset_version below kOldestSimDatasetVersion. A run whose training set is
/// gone or unreadable passes (there is nothing to tell), as does a directory without run.json;
/// a run.json that is not a run's is refused as RunDirectory::open refuses it.
/// Cost: reads run.json and the manifest.
void require_run_of_current_sim_dataset(const std::filesystem::path& run_dir);
/// The same for a run directory already opened: reads only the manifest.
void require_run_of_current_sim_dataset(const RunDirectory& run);

}  // namespace ropes::crl
