#!/usr/bin/python3
"""How many pixels an intervention changes: for each of a 2C dataset shard's anchors and each
joint's two interventions, the count of pixels per camera whose grey level differs from the
anchor's observational image by more than 8, and the intervened angle's change. Prints the
medians per joint (numpy only).

usage: pixel_change.py DATASET_DIR [SHARD]   (shard 0 by default)
"""
import sys

import numpy as np

data, shard = sys.argv[1], int(sys.argv[2]) if len(sys.argv) > 2 else 0
images = np.load(f"{data}/shards/images-{shard:05d}.npy", mmap_mode="r")
angles = np.load(f"{data}/shards/angles-{shard:05d}.npy")
per_anchor = 13  # the observational sample, then two interventions of each of 6 joints
for joint in range(1, 7):
    pixels, moved = [], []
    for a in range(len(angles) // per_anchor):
        base = images[a * per_anchor].astype(np.int16)
        for regime in (2 * joint - 1, 2 * joint):
            row = a * per_anchor + regime
            pixels.append((np.abs(images[row].astype(np.int16) - base) > 8).sum(axis=(1, 2)))
            moved.append(abs(angles[row][joint - 1] - angles[a * per_anchor][joint - 1]))
    print(f"joint {joint}: median changed pixels per camera {np.median(pixels, 0)}, "
          f"median angle change {np.median(moved):.2f} rad")
