#include "ropes_nn/build_info.hpp"

#include <Eigen/Core>

#include <string>
#include <vector>

#include "gemm.hpp"
#include "ropes_nn_revision.h"

namespace ropes::nn {

namespace {

// the level of this translation unit's compilation: the baseline's (ropes_nn's flags)
std::string compiled_level() {
#if defined(__x86_64__)
#if defined(__AVX512F__) && defined(__AVX512BW__) && defined(__AVX512CD__) && \
    defined(__AVX512DQ__) && defined(__AVX512VL__)
  std::string level = "x86-64-v4";
#elif defined(__AVX2__) && defined(__FMA__) && defined(__BMI2__) && defined(__F16C__)
  std::string level = "x86-64-v3";
#elif defined(__SSE4_2__) && defined(__POPCNT__) && defined(__SSSE3__)
  std::string level = "x86-64-v2";
#else
  std::string level = "x86-64";
#endif
#else
  std::string level = "other";
#endif
#if ROPES_NN_NATIVE
  level += " (-march=native)";
#endif
  return level;
}

}  // namespace

const BuildInfo& build_info() {
  static const BuildInfo info = [] {
    BuildInfo b;
    b.isa_level = gemm_kernels().level;
    b.isa_baseline = compiled_level();
    b.isa_build = ROPES_NN_ISA_BUILD;
    b.compiler = ROPES_NN_COMPILER;
    b.flags = ROPES_NN_FLAGS;
    b.eigen = std::to_string(EIGEN_WORLD_VERSION) + "." + std::to_string(EIGEN_MAJOR_VERSION) +
              "." + std::to_string(EIGEN_MINOR_VERSION);
    b.revision = ROPES_NN_REVISION;
    return b;
  }();
  return info;
}

std::vector<std::string> cpu_levels() {
  std::vector<std::string> levels;
#if defined(__x86_64__)
  __builtin_cpu_init();
#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 12
  // g++ knows the levels' whole feature sets (v3 also has F16C, LZCNT, MOVBE, ...)
  const bool v2 = __builtin_cpu_supports("x86-64-v2");
  const bool v3 = __builtin_cpu_supports("x86-64-v3");
  const bool v4 = __builtin_cpu_supports("x86-64-v4");
#else
  // clang (the sanitizer build): the features its builtin knows (clang 14 has no "f16c")
  const bool v2 = __builtin_cpu_supports("sse4.2") && __builtin_cpu_supports("popcnt") &&
                  __builtin_cpu_supports("ssse3");
  const bool v3 = v2 && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
                  __builtin_cpu_supports("bmi2");
  const bool v4 = v3 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                  __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx512dq") &&
                  __builtin_cpu_supports("avx512vl");
#endif
  if (v4)
    levels.push_back("x86-64-v4");
  if (v3)
    levels.push_back("x86-64-v3");
  if (v2)
    levels.push_back("x86-64-v2");
  levels.push_back("x86-64");
#endif
  return levels;
}

bool cpu_runs_build_level() {
  const std::string level =
      build_info().isa_baseline.substr(0, build_info().isa_baseline.find(' '));
  for (const std::string& l : cpu_levels())
    if (l == level)
      return true;
  return level == "other";
}

nlohmann::json provenance(int threads) {
  const BuildInfo& b = build_info();
  return {
      {"isa_level", b.isa_level},   {"isa_baseline", b.isa_baseline}, {"isa_build", b.isa_build},
      {"cpu_levels", cpu_levels()}, {"compiler", b.compiler},         {"flags", b.flags},
      {"eigen", b.eigen},           {"revision", b.revision},         {"threads", threads}};
}

std::vector<std::string> provenance_differences(const nlohmann::json& a, const nlohmann::json& b) {
  std::vector<std::string> out;
  auto field = [](const nlohmann::json& p, const char* key) {
    return p.is_object() && p.contains(key) && p[key].is_string() ? p[key].get<std::string>()
                                                                  : std::string("missing");
  };
  for (const char* key : {"isa_level", "isa_baseline", "compiler", "flags", "eigen"}) {
    const std::string va = field(a, key), vb = field(b, key);
    if (va != vb || va == "missing")
      out.push_back(std::string(key) + ": " + va + " vs " + vb);
  }
  return out;
}

}  // namespace ropes::nn
