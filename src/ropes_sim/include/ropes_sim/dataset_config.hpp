#pragma once
/// @file dataset_config.hpp
/// DatasetConfig: what ropes-generate makes, read from a JSON file
/// (share/ropes_sim/datasets/*.json):
///   name               the dataset's name
///   distribution       path of an InterventionSampler config (relative to this file)
///   robot              path of the URDF (relative to this file)
///   rig                "single_camera", "two_cameras" (CameraRig's built-in rigs), or an
///                      object {name, cameras: [{name, target [x,y,z], distance, yaw_deg,
///                      pitch_deg, fov_y_deg, near, far}]}; omitted camera fields take
///                      Camera's defaults
///   image              {width, height}: pixels, each in [8, 4096]
///   anchors            anchors in the dataset, >= 1
///   anchors_per_shard  anchors per shard file, >= 1
/// Unknown fields are errors, so that a misspelt one is not silently ignored.

#include <cstdint>
#include <filesystem>
#include <string>

#include "ropes_sim/camera.hpp"

namespace ropes::sim {

struct DatasetConfig {
  std::string name;
  std::filesystem::path file;          // the config file
  std::filesystem::path distribution;  // resolved
  std::filesystem::path robot;         // resolved
  CameraRig rig;                       // image size included
  std::int64_t anchors = 0;
  std::int64_t anchors_per_shard = 0;

  /// Reads and checks a config file; throws ConfigError (intervention_sampler.hpp) naming
  /// the file, the field, the value and what was expected.
  static DatasetConfig load(const std::filesystem::path& path);

  /// The configuration as a JSON object text, with the rig written out in full: what a
  /// dataset's manifest records (no paths, so that it does not depend on where files are).
  std::string to_json() const;
  std::int64_t shard_count() const { return (anchors + anchors_per_shard - 1) / anchors_per_shard; }
};

/// The installed dataset configs' directory, share/ropes_sim/datasets, found as
/// core::find_package_share finds it (beside the executable, a sourced install space, or
/// where this build installs).
std::filesystem::path installed_dataset_configs_dir();

/// The dataset config `name_or_path`: a file, else the installed config of that name
/// ("small-1c"); an empty path when it is neither (a name that is not a plain name, such as
/// "../x", is never looked up).
std::filesystem::path find_dataset_config(const std::string& name_or_path);

}  // namespace ropes::sim
