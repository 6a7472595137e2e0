#pragma once
// What ropes-generate and ropes-sim-stream share: configs given by name (usage errors and
// number flags: ropes_core/cli.hpp).
#include <filesystem>
#include <stdexcept>
#include <string>

#include "ropes_core/cli.hpp"
#include "ropes_sim/dataset_config.hpp"

namespace ropes::sim::tools {

namespace fs = std::filesystem;

using core::parse_number;
using core::UsageError;

// a config given by name is looked for among the installed ones (find_dataset_config)
inline fs::path find_config(const std::string& value) {
  const fs::path file = find_dataset_config(value);
  if (file.empty())
    throw UsageError("--config '" + value +
                     "' is neither a file nor an installed config name (1c, 2c, 2c_causal, ... "
                     "in " +
                     installed_dataset_configs_dir().string() + ")");
  return file;
}

}  // namespace ropes::sim::tools
