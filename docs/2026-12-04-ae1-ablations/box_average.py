#!/usr/bin/python3
"""Makes the antialiased screening dataset: averages every k x k block of a ropes dataset
rendered at k times the size (ropes-generate with a copy of the dataset config whose image is
k times larger; the same seed gives the same angles) into the dataset it would be at the
config's size, rounding to 8 bits. The manifest keeps the source's dataset id and names the
config CONFIG so that the experiment config accepts it; a screening aid, not a ropes_sim option.

usage: box_average.py SOURCE_DIR OUT_DIR K CONFIG   (e.g. data-512 data-ss4 4 small-2c)
"""
import hashlib
import json
import os
import shutil
import sys

import numpy as np

src, dst, k, config = sys.argv[1], sys.argv[2], int(sys.argv[3]), sys.argv[4]
manifest = json.load(open(os.path.join(src, "manifest.json")))
os.makedirs(os.path.join(dst, "shards"), exist_ok=True)
for col in manifest["columns"]:
    if col["name"] == "images":
        c, h, w = col["row_shape"]
        col["row_shape"] = [c, h // k, w // k]
meta = manifest["metadata"]
meta["image"] = {"height": meta["image"]["height"] // k, "width": meta["image"]["width"] // k}
meta["config"]["image"] = dict(meta["image"])
meta["config"]["name"] = config
meta["supersample_screening"] = k
for shard in manifest["shards"]:
    for name, f in shard["files"].items():
        source, target = os.path.join(src, f["path"]), os.path.join(dst, f["path"])
        if name == "images":
            a = np.load(source)
            n, c, h, w = a.shape
            b = a.reshape(n, c, h // k, k, w // k, k).astype(np.float32).mean(axis=(3, 5))
            np.save(target, np.clip(np.rint(b), 0, 255).astype(np.uint8))
        else:
            shutil.copyfile(source, target)
        f["bytes"] = os.path.getsize(target)
        f["sha256"] = hashlib.sha256(open(target, "rb").read()).hexdigest()
    index = shard["files"]["anchor"]["path"].split("-")[-1].split(".")[0]
    marker = json.load(open(os.path.join(src, "shards", index + ".json")))
    marker["files"] = shard["files"]
    json.dump(marker, open(os.path.join(dst, "shards", index + ".json"), "w"), indent=2)
json.dump(manifest, open(os.path.join(dst, "manifest.json"), "w"), indent=2)
if os.path.exists(os.path.join(src, "generation.json")):
    shutil.copyfile(os.path.join(src, "generation.json"), os.path.join(dst, "generation.json"))
