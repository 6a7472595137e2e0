// Finding an installed package's data: the order of the places, and a clear error naming them.
#include "ropes_core/package_share.hpp"

#include <gtest/gtest.h>
#include <unistd.h>

#include <cstdlib>
#include <filesystem>
#include <stdexcept>
#include <string>

namespace ropes::core {
namespace {

namespace fs = std::filesystem;

class PackageShare : public ::testing::Test {
 protected:
  void SetUp() override {
    dir_ = fs::temp_directory_path() / ("ropes_package_share_" + std::to_string(::getpid()));
    fs::remove_all(dir_);
    const char* old = std::getenv("CMAKE_PREFIX_PATH");
    had_ = old != nullptr;
    if (had_)
      old_ = old;
  }
  void TearDown() override {
    if (had_)
      ::setenv("CMAKE_PREFIX_PATH", old_.c_str(), 1);
    else
      ::unsetenv("CMAKE_PREFIX_PATH");
    fs::remove_all(dir_);
  }
  // <dir>/<prefix>/share/<package>/<probe>
  fs::path make(const std::string& prefix, const std::string& package, const std::string& probe) {
    const fs::path share = dir_ / prefix / "share" / package;
    fs::create_directories(share / probe);
    return share;
  }
  fs::path dir_;
  bool had_ = false;
  std::string old_;
};

TEST_F(PackageShare, ASourcedPrefixComesBeforeTheBuildTimeInstall) {
  const fs::path moved = make("moved", "ropes_probe", "configs");
  const fs::path original = make("original", "ropes_probe", "configs");
  ::setenv("CMAKE_PREFIX_PATH", ("/nonexistent:" + (dir_ / "moved").string()).c_str(), 1);
  EXPECT_EQ(find_package_share("ropes_probe", "configs", original), moved.lexically_normal());
  // a prefix without the probe is passed over
  EXPECT_EQ(
      find_package_share("ropes_probe", "datasets", make("original", "ropes_probe", "datasets")),
      original.lexically_normal());
}

TEST_F(PackageShare, TheBuildTimeInstallIsTheLastResort) {
  ::unsetenv("CMAKE_PREFIX_PATH");
  const fs::path original = make("original", "ropes_probe", "configs");
  EXPECT_EQ(find_package_share("ropes_probe", "configs", original), original.lexically_normal());
  const auto places = package_share_candidates("ropes_probe", original);
  ASSERT_GE(places.size(), 3u);
  EXPECT_EQ(places.back(), original);
  // beside this test executable first: <exe>/../share/<package>, then the isolated layout
  EXPECT_EQ(places[0].filename(), "ropes_probe");
  EXPECT_EQ(places[1], places[0].parent_path().parent_path().parent_path() / "ropes_probe" /
                           "share" / "ropes_probe");
}

TEST_F(PackageShare, NoneHoldingTheProbeIsAnErrorNamingEveryPlace) {
  ::setenv("CMAKE_PREFIX_PATH", (dir_ / "elsewhere").string().c_str(), 1);
  try {
    find_package_share("ropes_probe", "configs", dir_ / "gone");
    FAIL() << "found a package that is nowhere";
  } catch (const std::runtime_error& e) {
    const std::string m = e.what();
    EXPECT_NE(m.find("ropes_probe (share/ropes_probe/configs)"), std::string::npos) << m;
    EXPECT_NE(m.find((dir_ / "elsewhere" / "share" / "ropes_probe").string()), std::string::npos)
        << m;
    EXPECT_NE(m.find((dir_ / "gone").string()), std::string::npos) << m;
    EXPECT_NE(m.find("setup.bash"), std::string::npos) << m;
  }
}

}  // namespace
}  // namespace ropes::core
