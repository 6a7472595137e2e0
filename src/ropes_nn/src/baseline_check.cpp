// baseline_check.cpp: a CPU below the level ropes_nn was compiled for gets a clear error, not
// a SIGILL at whatever instruction comes first.
//
// Compiled for plain x86-64 whatever ROPES_ISA_BASELINE is (CMakeLists.txt), and run as a
// constructor of the highest priority, before the constructors of code compiled at the
// baseline. Every program linked with ropes_nn runs it: the static library's users link it
// through `--undefined=ropes_nn_check_cpu_baseline` (ropes_nn's interface link options).
// Plain C calls only: an inline function or template instantiated here could be merged at link
// time with a copy compiled at the baseline, which is what this file must not run.

#include <stdio.h>
#include <stdlib.h>
#include <string.h>
#include <unistd.h>

#ifndef ROPES_NN_BASELINE_LEVEL
#error "ROPES_NN_BASELINE_LEVEL (2, 3 or 4: the x86-64 level of ropes_nn's baseline) is not set"
#endif

extern "C" {

/// The highest x86-64 level of this CPU: 1 (x86-64) to 4 (x86-64-v4).
static int cpu_level() {
  __builtin_cpu_init();  // a constructor may run before libgcc's own initialisation
#if defined(__GNUC__) && !defined(__clang__) && __GNUC__ >= 12
  if (__builtin_cpu_supports("x86-64-v4"))
    return 4;
  if (__builtin_cpu_supports("x86-64-v3"))
    return 3;
  if (__builtin_cpu_supports("x86-64-v2"))
    return 2;
  return 1;
#else
  // clang 14 (the sanitizer build): the features its builtin knows, as build_info.cpp
  const int v2 = __builtin_cpu_supports("sse4.2") && __builtin_cpu_supports("popcnt") &&
                 __builtin_cpu_supports("ssse3");
  const int v3 = v2 && __builtin_cpu_supports("avx2") && __builtin_cpu_supports("fma") &&
                 __builtin_cpu_supports("bmi2");
  const int v4 = v3 && __builtin_cpu_supports("avx512f") && __builtin_cpu_supports("avx512bw") &&
                 __builtin_cpu_supports("avx512cd") && __builtin_cpu_supports("avx512dq") &&
                 __builtin_cpu_supports("avx512vl");
  return v4 ? 4 : v3 ? 3 : v2 ? 2 : 1;
#endif
}

static const char* level_name(int level) {
  switch (level) {
    case 4:
      return "x86-64-v4 (AVX-512)";
    case 3:
      return "x86-64-v3 (AVX2, FMA, BMI2)";
    case 2:
      return "x86-64-v2 (SSE4.2, POPCNT)";
    default:
      return "x86-64";
  }
}

/// ROPES_EMULATE_CPU_LEVEL=x86-64|x86-64-v2|x86-64-v3|x86-64-v4 makes this check see a CPU of
/// at most that level (how the error is tested on a CPU that has the baseline); 0 when unset,
/// -1 when set to anything else.
static int emulated_level() {
  const char* value = getenv("ROPES_EMULATE_CPU_LEVEL");
  if (value == nullptr || *value == '\0')
    return 0;
  if (strcmp(value, "x86-64") == 0)
    return 1;
  if (strcmp(value, "x86-64-v2") == 0)
    return 2;
  if (strcmp(value, "x86-64-v3") == 0)
    return 3;
  if (strcmp(value, "x86-64-v4") == 0)
    return 4;
  return -1;
}

static void fail(const char* message) {
  // write(2), not stdio: nothing of the program has run yet, and nothing is buffered
  ssize_t ignored = write(2, message, strlen(message));
  (void)ignored;
  _exit(1);
}

__attribute__((constructor(101))) void ropes_nn_check_cpu_baseline() {
  char message[640];
  int level = cpu_level();
  const int emulated = emulated_level();
  if (emulated < 0) {
    snprintf(message, sizeof message,
             "ropes_nn: ROPES_EMULATE_CPU_LEVEL is '%s'; expected x86-64, x86-64-v2, x86-64-v3 or "
             "x86-64-v4 (or unset)\n",
             getenv("ROPES_EMULATE_CPU_LEVEL"));
    fail(message);
  }
  if (emulated > 0 && emulated < level)
    level = emulated;
  if (level >= ROPES_NN_BASELINE_LEVEL)
    return;
  snprintf(message, sizeof message,
           "ropes_nn: this program was built for %s CPUs (ROPES_ISA_BASELINE), and this CPU is "
           "%s at most%s. Build the workspace for it: colcon build --cmake-args "
           "-DROPES_ISA_BASELINE=x86-64\n",
           level_name(ROPES_NN_BASELINE_LEVEL), level_name(level),
           emulated > 0 ? " (ROPES_EMULATE_CPU_LEVEL)" : "");
  fail(message);
}

}  // extern "C"
