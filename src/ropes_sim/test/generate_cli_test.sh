#!/bin/bash
# ropes-generate end to end: the 1C and 2C configs give datasets numpy opens (shapes, dtypes,
# per-file sha256 from hashlib), a run killed with SIGKILL and run again gives the same bytes
# as an uninterrupted one, --preview writes a PNG, and bad input exits non-zero with a message.
# usage: generate_cli_test.sh <ropes-generate> <dataset configs dir>
set -euo pipefail
gen=$1
configs=$(cd "$2" && pwd)
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT
py=/usr/bin/python3
fail() { echo "FAIL: $*"; exit 1; }

# 1. the 1C and 2C configs, small: numpy opens every shard and agrees with the manifest
for c in 1c 2c; do
  "$gen" --config "$configs/$c.json" --out "$work/$c" --seed 5 --anchors 5 \
    --anchors-per-shard 2 --threads 2 >/dev/null
  $py - "$work/$c" "$c" <<'PY'
import hashlib, json, sys
import numpy as np
d, name = sys.argv[1], sys.argv[2]
m = json.load(open(f"{d}/manifest.json"))
meta = m["metadata"]
regimes, cams = (7, 1) if name == "1c" else (13, 2)
assert meta["samples_per_anchor"] == regimes and len(meta["cameras"]) == cams, meta
# every regime parsed in the metadata (since sim_dataset_version 2)
assert meta["sim_dataset_version"] == 3 and len(meta["regimes"]) == regimes, meta
assert meta["regimes"][0] == {"name": "observational", "joint": None, "joint_index": None,
                              "intervention": None}, meta["regimes"][0]
rows = 0
for shard in m["shards"]:
    for col, f in shard["files"].items():
        raw = open(f"{d}/{f['path']}", "rb").read()
        assert hashlib.sha256(raw).hexdigest() == f["sha256"], f
    im = np.load(f"{d}/{shard['files']['images']['path']}")
    an = np.load(f"{d}/{shard['files']['angles']['path']}")
    rg = np.load(f"{d}/{shard['files']['regime']['path']}")
    ac = np.load(f"{d}/{shard['files']['anchor']['path']}")
    n = shard["rows"]
    assert im.dtype == np.uint8 and im.shape == (n, cams, 128, 128), im.shape
    assert an.dtype == np.float32 and an.shape == (n, 7), an.shape
    assert rg.dtype == np.int32 and ac.dtype == np.int64
    assert list(rg) == [i % regimes for i in range(rows, rows + n)], rg
    assert list(ac) == [i // regimes for i in range(rows, rows + n)], ac
    # an intervention changes the intervened joint only (independent model)
    for r in range(1, regimes):
        regime = meta["regimes"][r]
        j = regime["joint_index"]
        assert regime["name"] == meta["regime_names"][r] == \
            f"do({regime['joint']})={regime['intervention']}", regime
        assert meta["joint_names"][j] == regime["joint"] and regime["intervention"] in (1, 2)
        diff = np.nonzero(an[r::regimes][0] != an[0::regimes][0])[0] if len(an) > r else []
        assert all(k == j for k in diff), (r, diff)
    assert 30 < im.mean() < 230, im.mean()
    rows += n
assert rows == m["rows"] == 5 * regimes
print(f"numpy: {name}: {rows} rows, {cams} camera(s), hashes match")
PY
done

# 2. kill -9 in the middle, run again: the same bytes as one uninterrupted run
args=(--config "$configs/1c.json" --seed 9 --anchors 300 --anchors-per-shard 10)
"$gen" "${args[@]}" --out "$work/ref" --threads 1 >/dev/null
"$gen" "${args[@]}" --out "$work/killed" --threads 2 >/dev/null &
pid=$!
for _ in $(seq 1 600); do
  [ -e "$work/killed/shards/00004.json" ] && break
  sleep 0.01
done
kill -9 $pid 2>/dev/null || fail "ropes-generate finished before it could be killed"
wait $pid 2>/dev/null || true
done_before=$(ls "$work/killed/shards/" | grep -c '^[0-9]*\.json$' || true)
[ -e "$work/killed/manifest.json" ] && fail "killed run has a manifest"
"$gen" "${args[@]}" --out "$work/killed" --threads 2 | tail -1
diff -r "$work/ref" "$work/killed" || fail "resumed dataset differs from the uninterrupted one"
echo "resume: killed after $done_before of 30 shards; resumed dataset is byte-identical"

# 2b. the states a kill can leave, made by hand: a shard without its marker, a column file
# cut short, temporary files of dead processes; and a shard of another dataset copied in
cp -r "$work/killed" "$work/hurt"
rm "$work/hurt/manifest.json" "$work/hurt/shards/00007.json"
truncate -s 1000 "$work/hurt/shards/images-00012.npy"
echo partial > "$work/hurt/shards/angles-00020.npy.tmp.999999999"
echo partial > "$work/hurt/generation.json.tmp.999999998"
"$gen" --config "$configs/1c.json" --seed 10 --anchors 300 --anchors-per-shard 10 \
  --out "$work/seed10" --shard 3/30 >/dev/null
cp "$work/seed10/shards/"*00003* "$work/hurt/shards/"
"$gen" "${args[@]}" --out "$work/hurt" | tail -1
diff -r "$work/ref" "$work/hurt" || fail "repaired dataset differs from the uninterrupted one"
echo "repair: missing marker, truncated file, stale temporaries, foreign shard: byte-identical"

# 3. the preview
"$gen" --config "$configs/2c.json" --preview "$work/p.png" --seed 1 --anchor 3 >/dev/null
[ "$(head -c 8 "$work/p.png" | od -An -tx1 | tr -d ' ')" = "89504e470d0a1a0a" ] || fail "no PNG"
"$gen" --config "$configs/1c.json" --preview-extremes "$work/e.png" --seed 1 --anchors 50 >/dev/null
[ "$(head -c 8 "$work/e.png" | od -An -tx1 | tr -d ' ')" = "89504e470d0a1a0a" ] || fail "no PNG"

# 4. bad input: one clear line, non-zero exit, nothing overwritten
expect_error() {  # expected-text command...
  local want=$1; shift
  local out rc=0
  out=$("$@" 2>&1) || rc=$?
  [ $rc -ne 0 ] || fail "exit 0 for: $*"
  echo "$out" | grep -qF -- "$want" || fail "message '$out' lacks '$want'"
  out_last=$out
  echo "refused ($rc): $out"
}
before=$(cd "$work/ref" && find . -type f -exec sha256sum {} + | sort)
expect_error "holds a different dataset (manifest.json: /seed: 10 now, 9 there)" \
  "$gen" --config "$configs/1c.json" --seed 10 --anchors 300 --anchors-per-shard 10 --out "$work/ref"
after=$(cd "$work/ref" && find . -type f -exec sha256sum {} + | sort)
[ "$before" = "$after" ] || fail "a refused run changed the dataset"
expect_error "--seed is required" "$gen" --config "$configs/1c.json" --out "$work/x"
expect_error "--threads is '0'" "$gen" --config "$configs/1c.json" --out "$work/x" --seed 1 --threads 0
expect_error "--shard is '2/2'" "$gen" --config "$configs/1c.json" --out "$work/x" --seed 1 --shard 2/2
expect_error "neither a file nor an installed config" "$gen" --config nope --out "$work/x" --seed 1
expect_error "--preview writes one PNG" "$gen" --config "$configs/1c.json" --preview "$work/q.png" --out "$work/x"
echo '<robot name="r"><link name="a"/><joint name="j" type="revolute">' > "$work/bad.urdf"
sed -e "s|\.\./urdf/panda.urdf|$work/bad.urdf|" -e "s|\.\./distributions|$configs/../distributions|" \
  "$configs/1c.json" > "$work/badrobot.json"
expect_error "bad.urdf: not a valid URDF (urdfdom: " "$gen" --config "$work/badrobot.json" --out "$work/x" --seed 1
[ "$(echo "$out_last" | wc -l)" -eq 1 ] || fail "more than one line for a bad URDF: $out_last"
sed -e 's|"single_camera"|{"name": "sky", "cameras": [{"name": "up", "target": [0, 0, 30]}]}|' \
  -e "s|\.\./|$configs/../|g" "$configs/1c.json" > "$work/sky.json"
expect_error "rig camera 'up'" "$gen" --config "$work/sky.json" --out "$work/sky" --seed 1
[ ! -e "$work/sky" ] || fail "a refused config left $work/sky behind"
echo '{"name": "x"' > "$work/broken.json"
expect_error "broken.json: is not JSON" "$gen" --config "$work/broken.json" --out "$work/x" --seed 1
echo PASS
