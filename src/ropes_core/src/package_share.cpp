#include "ropes_core/package_share.hpp"

#include <cstdlib>
#include <stdexcept>
#include <system_error>

namespace ropes::core {

namespace fs = std::filesystem;

std::vector<fs::path> package_share_candidates(const std::string& package,
                                               const fs::path& installed_at) {
  std::vector<fs::path> places;
  // beside the executable: merged and isolated install layouts
  std::error_code ec;
  const fs::path exe = fs::read_symlink("/proc/self/exe", ec);
  if (!ec && exe.has_parent_path()) {
    const fs::path prefix = exe.parent_path().parent_path();
    places.push_back(prefix / "share" / package);
    places.push_back(prefix.parent_path() / package / "share" / package);
  }
  // the prefixes a sourced install space names
  if (const char* env = std::getenv("CMAKE_PREFIX_PATH")) {
    const std::string list = env;
    std::size_t start = 0;
    while (start <= list.size()) {
      const std::size_t colon = list.find(':', start);
      const std::string prefix =
          list.substr(start, colon == std::string::npos ? std::string::npos : colon - start);
      if (!prefix.empty())
        places.push_back(fs::path(prefix) / "share" / package);
      if (colon == std::string::npos)
        break;
      start = colon + 1;
    }
  }
  // where it was installed at build time
  if (!installed_at.empty())
    places.push_back(installed_at);
  return places;
}

fs::path find_package_share(const std::string& package, const std::string& probe,
                            const fs::path& installed_at) {
  const std::vector<fs::path> places = package_share_candidates(package, installed_at);
  std::string looked;
  for (const fs::path& place : places) {
    std::error_code ec;
    if (fs::exists(place / probe, ec))
      return place.lexically_normal();
    looked += (looked.empty() ? "" : ", ") + place.lexically_normal().string();
  }
  throw std::runtime_error("the installed files of " + package + " (share/" + package + "/" +
                           probe + ") are in none of the places looked: " + looked +
                           "; source the install space's setup.bash or reinstall it");
}

}  // namespace ropes::core
