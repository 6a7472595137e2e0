#!/usr/bin/env bash
# Builds the workspace with -DROPES_WITH_DDS=OFF in a scratch build and install space: every
# package that has the option (all but ropes_core and ropes_nn) must build, its tools must run the main job
# end to end (ropes-run on the tiny preset) and refuse the DDS flags with the reason, and
# ropes_msgs must install a config file that tells a consumer it was built without Fast DDS.
# The tests are not built here (BUILD_TESTING=OFF): DDS adds only executables and the tools'
# streaming sources (ropes-stream, ropes-sim-stream, ropes-train --status, ropes-eval --live);
# the libraries and the test executables compile from the same sources with and without it,
# and their tests run in the main build. Rebuilding and rerunning them here took 3 of this
# script's 5 minutes of CI (docs/2026-12-04-ci-time.md).
# ropes_core and ropes_nn have no DDS option, so they are not built again: the main install's
# are used. The build is -O1, which compiles in less time than Release's -O3, leaves out the
# benchmarks (they have no DDS part; the main build compiles them) and is a unity build
# (CMake's batches of 8 sources), as the sanitizer build is: 148 s instead of 235 s on 2 cores
# (docs/2026-12-04-ci-time.md). Its bits are not pinned; the Release build stays one source a
# translation unit.
# Usage: dds_off_test.sh WORKSPACE (its install/ropes_core and install/ropes_nn built)
set -euo pipefail
workspace=$(cd "$1" && pwd)
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
cd "$workspace"
colcon() { /usr/bin/colcon "$@"; }  # Debian's colcon, whatever python3 comes first on PATH
# colcon finds a skipped package in the install base it builds into: a copy of the main one's
mkdir -p "$scratch/install"
for pkg in ropes_core ropes_nn; do
  if [ ! -f "$workspace/install/$pkg/lib/cmake/$pkg/${pkg}Config.cmake" ]; then
    echo "FAIL: $workspace/install/$pkg is not installed; run colcon build first" >&2
    exit 1
  fi
  if grep -q "ROPES_WITH_DDS" "$workspace/src/$pkg/CMakeLists.txt"; then
    echo "FAIL: $pkg has a DDS option now; build it here again" >&2
    exit 1
  fi
  cp -a "$workspace/install/$pkg" "$scratch/install/$pkg"
done
colcon --log-base "$scratch/log" build --build-base "$scratch/build" --install-base "$scratch/install" \
  --packages-skip ropes_core ropes_nn --cmake-args -DCMAKE_BUILD_TYPE=Release \
  "-DCMAKE_CXX_FLAGS_RELEASE=-O1 -DNDEBUG" -DROPES_WITH_DDS=OFF -DROPES_BUILD_BENCH=OFF \
  -DROPES_PYTHON=OFF \
  -DBUILD_TESTING=OFF -DCMAKE_UNITY_BUILD=ON \
  --no-warn-unused-cli
grep -q "ROPES_WITH_DDS:STRING=OFF" "$scratch/build/ropes_msgs/CMakeCache.txt"
if [ -e "$scratch/install/ropes_msgs/include/ropes_msgs" ]; then
  echo "FAIL: ropes_msgs installed message headers with ROPES_WITH_DDS=OFF" >&2
  exit 1
fi
# no streaming executable without Fast DDS, and the flags that need it say so
for exe in ropes_msgs/bin/ropes-echo ropes_sim/bin/ropes-sim-stream ropes_crl/bin/ropes-stream; do
  if [ -e "$scratch/install/$exe" ]; then
    echo "FAIL: $exe installed with ROPES_WITH_DDS=OFF" >&2
    exit 1
  fi
done
set +e
status_out=$("$scratch/install/ropes_crl/bin/ropes-train" --status 2>&1); status_rc=$?
live_out=$("$scratch/install/ropes_eval/bin/ropes-eval" --live 2>&1); live_rc=$?
set -e
if [ "$status_rc" != 2 ] || ! grep -q "built without Fast DDS" <<< "$status_out" ||
   [ "$live_rc" != 2 ] || ! grep -q "built without Fast DDS" <<< "$live_out"; then
  echo "FAIL: --status / --live without DDS: rc $status_rc '$status_out', rc $live_rc '$live_out'" >&2
  exit 1
fi
# the tools end to end without DDS: ropes-run on the tiny preset (generate, train, evaluate,
# report)
if ! smoke=$("$scratch/install/ropes_eval/bin/ropes-run" 1c-tiny --out "$scratch/run" \
       --threads 2 --progress lines 2>&1) || [ ! -s "$scratch/run/report/results.md" ]; then
  echo "$smoke"
  echo "FAIL: ropes-run 1c-tiny built without DDS did not finish with a report" >&2
  exit 1
fi
# a consumer asking for ropes_msgs gets the reason
mkdir -p "$scratch/consumer"
cat > "$scratch/consumer/CMakeLists.txt" <<'CMAKE'
cmake_minimum_required(VERSION 3.22)
project(msgs_consumer NONE)
find_package(ropes_msgs CONFIG REQUIRED)
CMAKE
if cmake -S "$scratch/consumer" -B "$scratch/consumer/build" \
     -DCMAKE_PREFIX_PATH="$scratch/install/ropes_msgs" > "$scratch/consumer.log" 2>&1; then
  echo "FAIL: find_package(ropes_msgs) succeeded on a build without DDS" >&2
  exit 1
fi
tr -s ' \n' ' ' < "$scratch/consumer.log" | grep -q "was built without Fast DDS" \
  || { cat "$scratch/consumer.log"; echo "FAIL: no 'built without Fast DDS' message" >&2; exit 1; }
echo "PASS: every package builds with ROPES_WITH_DDS=OFF and ropes-run runs the main job"
