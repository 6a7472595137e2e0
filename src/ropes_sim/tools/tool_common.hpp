#pragma once
// What ropes-generate and ropes-sim-stream share: configs given by name (usage errors and
// number flags: ropes_core/cli.hpp).
#include <filesystem>
#include <stdexcept>
#include <string>

#include "ropes_core/cli.hpp"
#include "ropes_core/package_share.hpp"

namespace ropes::sim::tools {

namespace fs = std::filesystem;

using core::parse_number;
using core::UsageError;

// a config given by name is looked for among the installed ones (core::find_package_share)
inline fs::path find_config(const std::string& value) {
  if (fs::is_regular_file(value))
    return value;
  const fs::path dir =
      core::find_package_share("ropes_sim", "datasets", ROPES_SIM_INSTALL_SHARE_DIR) / "datasets";
  if (fs::is_regular_file(dir / (value + ".json")))
    return dir / (value + ".json");
  throw UsageError("--config '" + value +
                   "' is neither a file nor an installed config name (1c, 2c, 2c_causal, ... in " +
                   dir.string() + ")");
}

}  // namespace ropes::sim::tools
