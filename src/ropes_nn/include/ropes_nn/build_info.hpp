#pragma once
/// @file build_info.hpp
/// What built ropes_nn and what it runs on, for the provenance of seeded results.
///
/// A seeded run gives the same bytes on every CPU of the instruction-set level its kernels
/// were compiled for, at every thread count (parallel.hpp). Across levels, compilers or
/// Eigen versions the last bits of a float sum may differ, and after thousands of training
/// steps so do the metrics: run.json and results.json record this, and ropes-eval says so
/// when it compares results made under different builds.

#include <nlohmann/json.hpp>

#include <string>
#include <vector>

namespace ropes::nn {

/// The build of ropes_nn's kernels. Constant for the process.
struct BuildInfo {
  /// The x86-64 level of the GEMM kernels this process runs: "x86-64-v4" or "x86-64-v3" in the
  /// default build (run-time dispatch: the highest the CPU has, or ROPES_ISA=v3|v4), the
  /// baseline's level when the baseline is below v3 and the CPU below v3, and
  /// "<level> (-march=native)" in a native build, whose code may use instructions beyond its
  /// level ("other" off x86-64).
  std::string isa_level;
  /// The level the rest of ropes_nn was compiled for (ROPES_ISA_BASELINE, "x86-64-v3" by
  /// default; the native build's level with " (-march=native)").
  std::string isa_baseline;
  /// "dispatch" or "native" (the CMake option ROPES_ISA).
  std::string isa_build;
  /// The compiler and its version, e.g. "GNU 12.2.0".
  std::string compiler;
  /// The build type and the flags the kernels were compiled with.
  std::string flags;
  /// Eigen's version, e.g. "3.4.0".
  std::string eigen;
  /// The workspace's git revision when ropes_nn was built (`git describe --always --dirty`),
  /// or "unknown" outside a git checkout.
  std::string revision;
};

/// The build of this ropes_nn.
const BuildInfo& build_info();

/// The x86-64 levels this CPU supports, highest first (e.g. {"x86-64-v4", "x86-64-v3",
/// "x86-64-v2", "x86-64"}); empty off x86-64.
std::vector<std::string> cpu_levels();

/// Whether this CPU has the baseline's level (a native build's extra instructions beyond its
/// level are not checked). True off x86-64.
bool cpu_runs_build_level();

/// The provenance object run.json and results.json carry: {"isa_level", "isa_baseline",
/// "isa_build", "cpu_levels", "compiler", "flags", "eigen", "revision", "threads"}.
nlohmann::json provenance(int threads);

/// What differs between two provenance objects in what decides the bits (the kernels' level,
/// the baseline's, compiler, flags and Eigen version; not the revision, threads or CPU): one line
/// per field, "field: a vs b". Empty when a result made under `a` should have the bytes of one made
/// under `b`. Missing fields count as different ("missing").
std::vector<std::string> provenance_differences(const nlohmann::json& a, const nlohmann::json& b);

}  // namespace ropes::nn
