// Provenance (build_info.hpp): what is recorded is what built the library.
#include "ropes_nn/build_info.hpp"

#include <gtest/gtest.h>

#include <Eigen/Core>

#include <cstdio>
#include <cstdlib>
#include <string>

#include "ropes_core/child_process.hpp"

namespace ropes::nn {
namespace {

std::string output_of(const std::string& command) {
  std::string out = core::run_shell(command).output;
  while (!out.empty() && (out.back() == '\n' || out.back() == ' '))
    out.pop_back();
  return out;
}

TEST(BuildInfo, RecordsWhatBuiltTheLibrary) {
  const BuildInfo& b = build_info();
  EXPECT_EQ(b.eigen, std::to_string(EIGEN_WORLD_VERSION) + "." +
                         std::to_string(EIGEN_MAJOR_VERSION) + "." +
                         std::to_string(EIGEN_MINOR_VERSION));
  EXPECT_TRUE(b.compiler.rfind("GNU ", 0) == 0 || b.compiler.rfind("Clang ", 0) == 0) << b.compiler;
  EXPECT_NE(b.flags.find("-O"), std::string::npos) << b.flags;
  EXPECT_EQ(b.isa_level.rfind("x86-64", 0), 0u) << b.isa_level;
  EXPECT_EQ(b.isa_baseline.rfind("x86-64", 0), 0u) << b.isa_baseline;
  EXPECT_TRUE(b.isa_build == "dispatch" || b.isa_build == "native") << b.isa_build;
  // the kernels run at the highest level this CPU has among the compiled ones (v4 and v3 in
  // a dispatch build), unless ROPES_ISA names one
  if (b.isa_build == "dispatch" && std::getenv("ROPES_ISA") == nullptr &&
      cpu_levels().front() != "x86-64" && cpu_levels().front() != "x86-64-v2") {
    EXPECT_EQ(b.isa_level, cpu_levels().front());
  }
  // the witness: git itself, in the source tree the library was built from
  const std::string git =
      output_of("git -C " ROPES_NN_SOURCE_DIR " describe --always --dirty --abbrev=12 2>/dev/null");
  if (git.empty())
    EXPECT_EQ(b.revision, "unknown");
  else
    EXPECT_EQ(b.revision.substr(0, 12), git.substr(0, 12));
  // the machine runs what it built
  EXPECT_TRUE(cpu_runs_build_level()) << b.isa_level;
  ASSERT_FALSE(cpu_levels().empty());
  EXPECT_EQ(cpu_levels().back(), "x86-64");
}

TEST(BuildInfo, ProvenanceDifferencesNameWhatDecidesTheBits) {
  const nlohmann::json here = provenance(2);
  EXPECT_EQ(here["threads"], 2);
  EXPECT_EQ(here["isa_level"], build_info().isa_level);
  // threads, revision and CPU do not change the bits of a level's results
  nlohmann::json other = provenance(7);
  other["revision"] = "0123456789ab";
  other["cpu_levels"] = {"x86-64-v3", "x86-64-v2", "x86-64"};
  EXPECT_TRUE(provenance_differences(here, other).empty());
  // another level than this machine's (it ran at v3 on a v3 CPU, where "x86-64-v3" was no change)
  const std::string level = build_info().isa_level == "x86-64-v3" ? "x86-64-v4" : "x86-64-v3";
  other["isa_level"] = level;
  other["eigen"] = "3.3.9";
  EXPECT_EQ(provenance_differences(here, other),
            (std::vector<std::string>{"isa_level: " + build_info().isa_level + " vs " + level,
                                      "eigen: " + build_info().eigen + " vs 3.3.9"}));
  // a result from before provenance was recorded
  EXPECT_EQ(provenance_differences(here, nlohmann::json()).size(), 5u);
}

}  // namespace
}  // namespace ropes::nn
