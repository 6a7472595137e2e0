"""ROPES from Python, in a minute: render the Panda, generate the `tiny` datasets, train the
three stages, evaluate by the paper's protocol and estimate joint angles from images.

Run it after building the workspace (Debian's python3, which has numpy):

    . install/setup.bash
    python3 examples/python/quickstart.py [OUT]      # OUT: where it writes (quickstart-out)

Each cell (# %%) runs on its own in a notebook too. A second run reuses what the first made:
generation and training resume, and stop at once when they are complete.
"""
# %% Setup
import sys
import time

import numpy as np

import ropes
from ropes import crl, dataset, sim

out = sys.argv[1] if len(sys.argv) > 1 else "quickstart-out"
start = time.monotonic()

# %% The robot: a URDF, its forward kinematics, and the dataset config's camera rig
config = sim.DatasetConfig.load("tiny-1c")  # installed with ropes_sim; a file path works too
robot = sim.Robot(config.robot)
q = np.zeros(len(robot.joints))
hand = robot.link_poses(q)["panda_hand"]
print(f"{robot.name}: {len(robot.joints)} joints; the hand at q = 0 is at {hand[:3, 3].round(3)}")
rig = sim.Rig(config)
image = rig.render(np.zeros(len(rig.joint_names)))
print(f"rig {rig.camera_names}: images {image.shape} {image.dtype}, "
      f"{(rig.robot_masks(np.zeros(len(rig.joint_names))) > 0).mean():.0%} robot pixels")

# %% Data: the interventional training set (seed 0) and a test set (seed 1)
for seed, name in ((0, "train"), (1, "test")):
    result = sim.generate_dataset(config, f"{out}/{name}-data", seed=seed, threads=2)
    print(f"{name} data: {result.images} images rendered, complete: {result.complete}")
train = dataset.Dataset(f"{out}/train-data")
print(f"{len(train)} rows; regimes {train.regime_names}")


# %% Training: AE1, one LDR classifier per joint, AE2 with the score-sparsity loss
# (ropes-train's log lines go to stderr; the callback gets every metrics record as a dict
# and could stop the run by returning False)
records = []
run = crl.train("1c-tiny", f"{out}/train-data", f"{out}/run", seed=0, threads=2,
                progress=records.append)
stages = sorted({r["stage"] for r in records})
print(f"run complete: {run.complete}; {len(records)} metrics records from stages {stages}")

# %% Evaluation by the paper's protocol (the tiny test set holds 40 observational samples)
ev = ropes.eval.evaluate_run(f"{out}/run", f"{out}/test-data", repeats=3,
                             calibration_samples=20, test_samples=20, probe_steps=100,
                             threads=2)
print(ev.table)

# %% Estimation: images in, joint angles out, with the calibration the evaluation wrote
est = crl.Estimator(f"{out}/run")
test = dataset.Dataset(f"{out}/test-data")
rows = test.regime("observational")
latents, angles = est.estimate(test.take("images", rows))
names = test.metadata["joint_names"]
truth = test.take("angles", rows)[:, [names.index(j) for j in est.joints]]
mcc = ropes.eval.mcc(latents, truth)
print(f"{'joint':<14}{'MCC':>8}{'MSE (rad^2)':>14}")
for k, joint in enumerate(est.joints):
    print(f"{joint:<14}{mcc[k]:>8.3f}{np.mean((angles[:, k] - truth[:, k]) ** 2):>14.3f}")
print(f"(all {len(rows)} observational test samples; the calibration was fitted on 20 of them)")
print(f"done in {time.monotonic() - start:.0f} s; everything is in {out}/")
