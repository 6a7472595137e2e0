#!/usr/bin/env bash
# Builds tests/consumer against a colcon install space and runs it; then asks for an
# incompatible major version of ropes_nn and expects CMake's version message.
# Usage: consumer_test.sh INSTALL_DIR WORK_DIR
set -euo pipefail
install_dir=$1
work=$2
here=$(cd "$(dirname "$0")" && pwd)
[ -f "$install_dir/setup.bash" ] || { echo "no colcon install space at $install_dir" >&2; exit 1; }
rm -rf "$work" && mkdir -p "$work"

# what a user of another workspace does: source the install space, find_package
set +u
# shellcheck disable=SC1091
. "$install_dir/setup.bash"
set -u

echo "== consumer: find_package(ropes_core 0.1), (ropes_nn 0.1) and (ropes_eval 0.1)"
cmake -S "$here/consumer" -B "$work/ok" -DCMAKE_BUILD_TYPE=Release > "$work/ok.log" 2>&1 \
  || { cat "$work/ok.log"; exit 1; }
cmake --build "$work/ok" > "$work/ok-build.log" 2>&1 || { cat "$work/ok-build.log"; exit 1; }
"$work/ok/ropes_consumer" | tee "$work/default.out"

echo "== consumer: ROPES_ISA=v3, the kernels an AVX2-only CPU runs (when this CPU has AVX2)"
if grep -qw avx2 /proc/cpuinfo && grep -q "build dispatch" "$work/default.out"; then
  ROPES_ISA=v3 "$work/ok/ropes_consumer" | tee "$work/v3.out"
  grep -q "kernels x86-64-v3 " "$work/v3.out" \
    || { echo "FAIL: ROPES_ISA=v3 did not run the v3 kernels" >&2; exit 1; }
  # another level orders the sums otherwise: the same code to float rounding, not bit for bit
  a=$(sed -n 's/.*checksum \(.*\)/\1/p' "$work/default.out")
  b=$(sed -n 's/.*checksum \(.*\)/\1/p' "$work/v3.out")
  awk -v a="$a" -v b="$b" 'BEGIN { d = a - b; if (d < 0) d = -d; s = (a < 0 ? -a : a);
    exit !(d <= 1e-3 * (s > 1 ? s : 1)) }' \
    || { echo "FAIL: the v3 checksum $b is far from the default's $a" >&2; exit 1; }
  echo "== consumer: ROPES_ISA=v9 is refused, naming the levels"
  if ROPES_ISA=v9 "$work/ok/ropes_consumer" > "$work/v9.out" 2>&1; then
    echo "FAIL: ROPES_ISA=v9 ran" >&2
    exit 1
  fi
  grep -q "ROPES_ISA=v9: not a level of this build; expected one of v4, v3" "$work/v9.out" \
    || { cat "$work/v9.out"; echo "FAIL: no message naming the levels" >&2; exit 1; }
  echo "== consumer: a CPU below the baseline (emulated) is refused before anything runs"
  rc=0
  ROPES_EMULATE_CPU_LEVEL=x86-64-v2 "$work/ok/ropes_consumer" > "$work/v2.out" 2> "$work/v2.err" \
    || rc=$?
  cat "$work/v2.err"
  [ "$rc" = 1 ] && [ ! -s "$work/v2.out" ] && grep -q "built for x86-64-v3" "$work/v2.err" \
    || { echo "FAIL: exit $rc; expected 1, no output and the baseline's message" >&2; exit 1; }
else
  echo "(skipped: no AVX2 here, or not a dispatch build)"
fi

echo "== consumer: the metrics link no renderer (neither ropes_sim nor OSMesa)"
link="$work/ok/CMakeFiles/ropes_consumer.dir/link.txt"
[ -f "$link" ] || { echo "FAIL: no link line at $link" >&2; exit 1; }
if grep -qiE 'ropes_sim|osmesa' "$link"; then
  cat "$link"
  echo "FAIL: the consumer of ropes_eval links the renderer" >&2
  exit 1
fi

echo "== consumer: the pipeline API (ropes_eval::pipeline) runs the main job and the suites"
"$work/ok/ropes_pipeline_consumer" "$work/pipeline" > "$work/pipeline.out" 2>&1 \
  || { cat "$work/pipeline.out"; echo "FAIL: the pipeline consumer" >&2; exit 1; }
grep "^pipeline consumer" "$work/pipeline.out"

echo "== consumer: allocation_counter.hpp (it defines malloc) is no header of ropes_nn's library"
if [ -n "$(find "$install_dir" -path '*/include/ropes_nn/allocation_counter.hpp')" ] ||
  [ -z "$(find "$install_dir" -path '*/share/ropes_nn/test_support/ropes_nn/allocation_counter.hpp')" ]
then
  echo "FAIL: allocation_counter.hpp is on ropes_nn's include path, or not in its test_support" >&2
  exit 1
fi

echo "== consumer: find_package(ropes_nn 1.0) must fail with CMake's version message"
if cmake -S "$here/consumer" -B "$work/bad" -DROPES_NN_VERSION=1.0 > "$work/bad.log" 2>&1; then
  cat "$work/bad.log"
  echo "FAIL: configuring with ropes_nn 1.0 succeeded" >&2
  exit 1
fi
expected='Could not find a configuration file for package "ropes_nn" that is compatible'
expected+=' with requested version "1.0"'
if ! tr -s ' \n' ' ' < "$work/bad.log" | grep -qF "$expected"; then
  cat "$work/bad.log"
  echo "FAIL: no version message '$expected'" >&2
  exit 1
fi
grep -A3 "Could not find a configuration file" "$work/bad.log" | head -6
echo "PASS"
