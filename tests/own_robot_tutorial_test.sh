#!/usr/bin/env bash
# The tutorial examples/own_robot/README.md runs as written: its command block (after the
# "tutorial commands" marker), in a scratch directory that holds the workspace's install/
# and examples/ as links. SIZE small runs it with the small configs instead of the tiny ones
# (minutes; label preset). Prints the run's per-joint table.
# Usage: own_robot_tutorial_test.sh WORKSPACE INSTALL SCRATCH [tiny|small]
set -euo pipefail
workspace=$1 install=$2 scratch=$3 size=${4:-tiny}
case "$size" in tiny | small) ;; *) echo "SIZE is '$size'; expected tiny or small" >&2; exit 2 ;; esac
readme=$workspace/examples/own_robot/README.md
block=$(awk '/<!-- tutorial commands/{marked=1; next} marked && /^```sh$/{inside=1; next}
             inside && /^```$/{exit} inside{print}' "$readme")
[ -n "$block" ] || { echo "FAIL: no tutorial command block in $readme" >&2; exit 1; }
if [ "$size" = small ]; then
  block=${block//-tiny/-small}
fi
rm -rf "$scratch" && mkdir -p "$scratch" && cd "$scratch"
ln -s "$install" install
ln -s "$workspace/examples" examples
echo "$block" > tutorial.sh
set +e
bash -e -o pipefail tutorial.sh > out.txt 2>&1  # -e: a failing command fails the test
rc=$?
set -e
tail -n 40 out.txt
[ "$rc" = 0 ] || { echo "FAIL: the tutorial's commands exited with $rc" >&2; exit 1; }
results=my_robot/run-$size/report/results.json
[ -f "$results" ] || { echo "FAIL: no $results" >&2; exit 1; }
[ -f my_robot/extremes.png ] || { echo "FAIL: no extremes.png" >&2; exit 1; }
grep -q "every link origin stays in view" out.txt || { echo "FAIL: no framing check" >&2; exit 1; }
/usr/bin/python3 - "$results" <<'PY'
import json, sys
r = json.load(open(sys.argv[1]))
suite = next(s for s in r["suites"] if s["name"] == "id")
ropes = suite["results"]["methods"]["ropes"]
joints = suite["results"]["joints"]
assert joints == ["shoulder", "elbow", "wrist"], joints
print("own robot:", ", ".join(f"{j} MCC {m:.3f}" for j, m in zip(joints, ropes["mcc"])))
PY
echo "own robot tutorial ($size): OK"
