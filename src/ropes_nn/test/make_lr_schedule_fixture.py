#!/usr/bin/python3
"""Reference learning rates from PyTorch's schedulers for test/lr_schedule_test.cpp.

Uses Debian's python3-torch (1.13) and writes test/fixtures/lr_schedules.json: for each case
the schedule's parameters and the rate PyTorch's scheduler gives at every step. Regenerate:
    apt-get install python3-torch
    /usr/bin/python3 src/ropes_nn/test/make_lr_schedule_fixture.py
"""
import json
import os

import torch


def rates(make_scheduler, lr, steps):
    """The rate of each of `steps` updates: read before the update, then scheduler.step()."""
    param = torch.nn.Parameter(torch.zeros(1))
    optimizer = torch.optim.Adam([param], lr=lr)
    scheduler = make_scheduler(optimizer)
    out = []
    for _ in range(steps):
        out.append(optimizer.param_groups[0]["lr"])
        optimizer.step()
        scheduler.step()
    return out


S = torch.optim.lr_scheduler
cases = {
    "linear_warmup": {
        "params": {"lr": 1e-3, "warmup_steps": 10},
        "rates": rates(lambda o: S.LinearLR(o, start_factor=1 / 10, end_factor=1.0, total_iters=9),
                       1e-3, 30),
    },
    "cosine": {
        "params": {"lr": 2e-3, "total_steps": 50, "final_lr": 1e-5, "warmup_steps": 0},
        "rates": rates(lambda o: S.CosineAnnealingLR(o, T_max=50, eta_min=1e-5), 2e-3, 51),
    },
    "cosine_with_warmup": {
        "params": {"lr": 3e-3, "total_steps": 40, "final_lr": 1e-4, "warmup_steps": 8},
        "rates": rates(lambda o: S.SequentialLR(o, [
            S.LinearLR(o, start_factor=1 / 8, end_factor=1.0, total_iters=7),
            S.CosineAnnealingLR(o, T_max=32, eta_min=1e-4)], milestones=[8]), 3e-3, 41),
    },
    "one_cycle": {
        "params": {"lr": 1e-2, "total_steps": 100, "pct_start": 0.3, "div_factor": 25.0,
                   "final_div_factor": 1e4},
        "rates": rates(lambda o: S.OneCycleLR(o, max_lr=1e-2, total_steps=100,
                                              cycle_momentum=False), 1e-2, 100),
    },
    "one_cycle_short": {
        "params": {"lr": 0.5, "total_steps": 7, "pct_start": 0.25, "div_factor": 10.0,
                   "final_div_factor": 100.0},
        "rates": rates(lambda o: S.OneCycleLR(o, max_lr=0.5, total_steps=7, pct_start=0.25,
                                              div_factor=10.0, final_div_factor=100.0,
                                              cycle_momentum=False), 0.5, 7),
    },
}
path = os.path.join(os.path.dirname(__file__), "fixtures", "lr_schedules.json")
with open(path, "w") as f:
    json.dump({"torch": torch.__version__, "cases": cases}, f, indent=1, sort_keys=True)
    f.write("\n")
print("wrote", path)
