#!/usr/bin/env bash
# A program linked with ropes_nn, run on a CPU below ropes_nn's baseline, must stop before any
# of its code runs with a clear error (src/baseline_check.cpp), not die of SIGILL. This CPU has
# the baseline, so the test emulates a lower one with ROPES_EMULATE_CPU_LEVEL.
# Usage: cpu_baseline_test.sh PROGRAM BASELINE   (BASELINE: x86-64-v3 or x86-64-v4)
set -uo pipefail
program=$1 baseline=$2
failed=0
fail() { echo "FAIL: $*" >&2; failed=1; }

# 1. a CPU one level below: exit status 1, the message, and nothing of the program ran
below=x86-64-v2
[ "$baseline" = x86-64-v4 ] && below=x86-64-v3
out=$(ROPES_EMULATE_CPU_LEVEL=$below "$program" 2>/tmp/ropes_cpu_baseline_err.$$)
rc=$?
err=$(cat /tmp/ropes_cpu_baseline_err.$$)
rm -f /tmp/ropes_cpu_baseline_err.$$
echo "emulated $below: exit $rc: $err"
[ "$rc" = 1 ] || fail "exit status $rc on an emulated $below CPU; expected 1"
[ -z "$out" ] || fail "the program ran on an emulated $below CPU: $out"
grep -q "built for $baseline" <<<"$err" || fail "the error does not name the baseline $baseline"
grep -q -- "-DROPES_ISA_BASELINE=x86-64" <<<"$err" || fail "the error does not say how to build for this CPU"

# 2. a CPU at the baseline runs the program
if ! out=$(ROPES_EMULATE_CPU_LEVEL=$baseline "$program" 2>&1); then
  fail "the program failed on an emulated $baseline CPU: $out"
fi

# 3. a bad value of the variable is refused, naming it
err=$(ROPES_EMULATE_CPU_LEVEL=v2 "$program" 2>&1 >/dev/null)
rc=$?
[ "$rc" = 1 ] && grep -q "ROPES_EMULATE_CPU_LEVEL is 'v2'" <<<"$err" \
  || fail "ROPES_EMULATE_CPU_LEVEL=v2 gave exit $rc: $err"

exit "$failed"
