#!/usr/bin/env bash
# An install space moved or copied elsewhere finds its own installed files
# (core::find_package_share), not the ones at the path it was built for: the copy gets a probe
# config that the original does not have, and the copy's tools, run with nothing sourced, must
# find it by name.
# Usage: relocation_test.sh INSTALL_DIR
set -euo pipefail
install_dir=$(cd "$1" && pwd)
scratch=$(mktemp -d)
trap 'rm -rf "$scratch"' EXIT
moved="$scratch/elsewhere/install"
mkdir -p "$scratch/elsewhere"
for pkg in ropes_core ropes_nn ropes_msgs ropes_sim ropes_crl ropes_eval; do
  [ -d "$install_dir/$pkg" ] || { echo "FAIL: $install_dir/$pkg is not installed" >&2; exit 1; }
done
cp -a "$install_dir" "$moved"
sed 's/"name": "tiny-1c"/"name": "moved-probe"/' \
  "$moved/ropes_sim/share/ropes_sim/datasets/tiny-1c.json" \
  > "$moved/ropes_sim/share/ropes_sim/datasets/moved-probe.json"
sed 's/"name": "1c-tiny"/"name": "moved-probe"/' \
  "$moved/ropes_crl/share/ropes_crl/configs/1c-tiny.json" \
  > "$moved/ropes_crl/share/ropes_crl/configs/moved-probe.json"
for f in "$install_dir/ropes_sim/share/ropes_sim/datasets/moved-probe.json" \
         "$install_dir/ropes_crl/share/ropes_crl/configs/moved-probe.json"; do
  [ ! -e "$f" ] || { echo "FAIL: the original install has $f; remove it" >&2; exit 1; }
done
clean_env=(env -u CMAKE_PREFIX_PATH -u AMENT_PREFIX_PATH -u COLCON_PREFIX_PATH)

echo "== the moved ropes-generate renders a config only the moved copy has"
"${clean_env[@]}" "$moved/ropes_sim/bin/ropes-generate" --config moved-probe \
  --preview "$scratch/preview.png" > "$scratch/generate.log" 2>&1 \
  || { cat "$scratch/generate.log"; echo "FAIL: ropes-generate did not find moved-probe" >&2; exit 1; }
[ -s "$scratch/preview.png" ] || { echo "FAIL: no preview written" >&2; exit 1; }

echo "== the moved ropes-train reads a config only the moved copy has"
rc=0
"${clean_env[@]}" "$moved/ropes_crl/bin/ropes-train" --config moved-probe --data "$scratch/no-data" \
  --out "$scratch/run" > "$scratch/train.log" 2>&1 || rc=$?
cat "$scratch/train.log"
# the config is found: the run stops at the missing dataset instead
if grep -q "neither a file nor an installed config" "$scratch/train.log" ||
   ! grep -q "no-data" "$scratch/train.log" || [ "$rc" = 0 ]; then
  echo "FAIL: ropes-train (exit $rc) did not find moved-probe in the moved install" >&2
  exit 1
fi

echo "== the original install does not see the moved copy's config"
rc=0
"${clean_env[@]}" "$install_dir/ropes_sim/bin/ropes-generate" --config moved-probe \
  --preview "$scratch/original.png" > "$scratch/original.log" 2>&1 || rc=$?
cat "$scratch/original.log"
[ "$rc" = 2 ] && grep -q "neither a file nor an installed config name" "$scratch/original.log" \
  || { echo "FAIL: the original ropes-generate gave exit $rc" >&2; exit 1; }
echo "PASS"
