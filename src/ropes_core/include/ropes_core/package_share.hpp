#pragma once
/// @file package_share.hpp
/// Where an installed package's data is (share/<package>/: configs, datasets' configs, the
/// paper's numbers), found at run time, so that an install space works after it was moved or
/// copied. The one way every package looks for its installed files.
#include <filesystem>
#include <string>
#include <vector>

namespace ropes::core {

/// The places find_package_share looks, in order, for share/<package>:
///  1. beside the running executable (/proc/self/exe): <exe>/../share/<package> (a merged
///     install) and <exe>/../../<package>/share/<package> (colcon's isolated install, where a
///     tool of one package reads another's data);
///  2. <prefix>/share/<package> for each prefix of $CMAKE_PREFIX_PATH (what an install
///     space's setup.bash sets, so a program built elsewhere finds a sourced install);
///  3. `installed_at`, the directory the package was installed to at build time.
std::vector<std::filesystem::path> package_share_candidates(
    const std::string& package, const std::filesystem::path& installed_at);

/// The first of package_share_candidates(package, installed_at) that holds `probe` (a file or
/// directory relative to share/<package>, such as "configs"). Throws std::runtime_error naming
/// the package, the probe and every place looked when none does.
std::filesystem::path find_package_share(const std::string& package, const std::string& probe,
                                         const std::filesystem::path& installed_at);

}  // namespace ropes::core
