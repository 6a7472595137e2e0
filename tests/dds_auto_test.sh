#!/usr/bin/env bash
# ropes_msgs as if Fast DDS were not installed (CMAKE_DISABLE_FIND_PACKAGE_fastrtps hides it):
# AUTO configures without the types and says why; ON stops with the missing parts named;
# a value other than AUTO/ON/OFF is refused.
# Usage: dds_auto_test.sh WORKSPACE (its install/ropes_core built: ropes_msgs is declared with
# ropes_core's CMake module)
set -euo pipefail
workspace=$(cd "$1" && pwd)
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
src="$workspace/src/ropes_msgs"
core=(-DCMAKE_PREFIX_PATH="$workspace/install/ropes_core")
hide=("${core[@]}" -DCMAKE_DISABLE_FIND_PACKAGE_fastrtps=ON -DBUILD_TESTING=OFF)

cmake -S "$src" -B "$scratch/auto" "${hide[@]}" > "$scratch/auto.log" 2>&1 \
  || { cat "$scratch/auto.log"; echo "FAIL: AUTO without Fast DDS did not configure" >&2; exit 1; }
grep -q "fastrtps (libfastrtps-dev)" "$scratch/auto.log" \
  || { cat "$scratch/auto.log"; echo "FAIL: AUTO did not name the missing fastrtps" >&2; exit 1; }
grep -q "set(ropes_msgs_WITH_DDS FALSE)" "$scratch/auto/ropes_msgsConfig.cmake" \
  || { echo "FAIL: the config file does not say it was built without DDS" >&2; exit 1; }
echo "AUTO without Fast DDS: $(grep 'ropes_msgs:' "$scratch/auto.log" | head -1)"

if cmake -S "$src" -B "$scratch/on" "${hide[@]}" -DROPES_WITH_DDS=ON > "$scratch/on.log" 2>&1; then
  echo "FAIL: ROPES_WITH_DDS=ON configured without Fast DDS" >&2
  exit 1
fi
grep -q "ROPES_WITH_DDS=ON but not found: fastrtps (libfastrtps-dev)" "$scratch/on.log" \
  || { cat "$scratch/on.log"; echo "FAIL: ON did not name what is missing" >&2; exit 1; }
echo "ON without Fast DDS: refused, naming fastrtps"

if cmake -S "$src" -B "$scratch/bad" "${core[@]}" -DROPES_WITH_DDS=maybe > "$scratch/bad.log" 2>&1; then
  echo "FAIL: ROPES_WITH_DDS=maybe was accepted" >&2
  exit 1
fi
grep -q "ROPES_WITH_DDS is 'maybe'; expected AUTO, ON or OFF" "$scratch/bad.log" \
  || { cat "$scratch/bad.log"; echo "FAIL: no message for ROPES_WITH_DDS=maybe" >&2; exit 1; }
echo "PASS"
