#!/usr/bin/python3
"""The witness beside ropes-eval --screen: how much of each joint a supervised CNN reads from a
ropes dataset's raw images, without AE1. Fitted on the anchors below 80 % of the anchor count
and scored on the others (the screening's sizes: 800 and 200 anchors of 1,000, though it
draws its 200 by a seeded shuffle), all six joints at once, standardized.
Both cameras' 128x128 images enter as two channels. PyTorch from Debian's python3-torch.

usage: pixel_probe.py DATASET_DIR [EPOCHS]   (prints the held-out R^2 per joint each epoch)
"""
import glob
import sys
import time

import numpy as np
import torch
import torch.nn as nn

torch.manual_seed(0)
np.random.seed(0)
torch.set_num_threads(2)
data = sys.argv[1]
epochs = int(sys.argv[2]) if len(sys.argv) > 2 else 6


def column(name):
    return np.concatenate([np.load(f) for f in sorted(glob.glob(f"{data}/shards/{name}-*.npy"))])


images, angles, anchor = column("images"), column("angles")[:, :6], column("anchor")
train = anchor < int(0.8 * (anchor.max() + 1))
mean, std = angles[train].mean(0), angles[train].std(0)
x = torch.from_numpy(images)
y = torch.from_numpy((angles - mean) / std).float()


def stage(cin, cout):
    return nn.Sequential(nn.Conv2d(cin, cout, 3, 2, 1), nn.GroupNorm(8, cout), nn.SiLU(),
                         nn.Conv2d(cout, cout, 3, 1, 1), nn.GroupNorm(8, cout), nn.SiLU())


net = nn.Sequential(stage(x.shape[1], 16), stage(16, 32), stage(32, 64), stage(64, 64),
                    nn.Flatten(), nn.Linear(64 * (x.shape[2] // 16) * (x.shape[3] // 16), 256),
                    nn.SiLU(), nn.Linear(256, 6))
rows_train, rows_test = np.nonzero(train)[0], np.nonzero(~train)[0]
per_epoch = len(rows_train) // 64
optimizer = torch.optim.Adam(net.parameters(), 1e-3)
schedule = torch.optim.lr_scheduler.OneCycleLR(optimizer, 2e-3, total_steps=epochs * per_epoch)
start = time.time()
for epoch in range(epochs):
    net.train()
    order = np.random.permutation(rows_train)
    for b in range(per_epoch):
        rows = order[b * 64:(b + 1) * 64]
        loss = ((net(x[rows].float() / 255) - y[rows]) ** 2).mean()
        optimizer.zero_grad()
        loss.backward()
        optimizer.step()
        schedule.step()
    net.eval()
    with torch.no_grad():
        pred = torch.cat([net(x[rows_test[i:i + 256]].float() / 255)
                          for i in range(0, len(rows_test), 256)])
    r2 = 1 - ((pred - y[rows_test]) ** 2).mean(0) / y[rows_test].var(0, unbiased=False)
    print(f"epoch {epoch + 1} {time.time() - start:.0f} s, held-out R^2 "
          + " / ".join(f"{v:.3f}" for v in r2.tolist()), flush=True)
