#!/usr/bin/env bash
# examples/python/quickstart.py runs as the README says (after `. install/setup.bash`, with
# Debian's python3), in a scratch directory, and prints its per-joint table.
# Usage: python_quickstart_test.sh WORKSPACE INSTALL SCRATCH
set -euo pipefail
workspace=$1 install=$2 scratch=$3
[ -f "$install/setup.bash" ] || { echo "no colcon install space at $install" >&2; exit 1; }
# built without the bindings (ROPES_PYTHON=OFF, or AUTO without pybind11): nothing to run
if ! compgen -G "$install/ropes_core/lib/python3*/site-packages/ropes/_core*.so" > /dev/null; then
  echo "skipped: $install has no Python bindings (ropes._core)"
  exit 77
fi
rm -rf "$scratch" && mkdir -p "$scratch" && cd "$scratch"
set +u  # colcon's setup scripts read unset variables
# shellcheck disable=SC1091
. "$install/setup.bash"
set -u
rc=0
/usr/bin/python3 "$workspace/examples/python/quickstart.py" > out.txt 2> err.txt || rc=$?
if [ "$rc" != 0 ]; then
  cat out.txt err.txt
  echo "FAIL: quickstart.py exited with $rc" >&2
  exit 1
fi
cat out.txt
for want in "joint              MCC   MSE (rad^2)" "panda_joint2 " "panda_joint6 " "done in "; do
  grep -qF -- "$want" out.txt || { echo "FAIL: the output lacks '$want'" >&2; exit 1; }
done
[ -f quickstart-out/run-eval/calibration.json ] || { echo "FAIL: no calibration written" >&2; exit 1; }
echo "python quickstart: OK"
