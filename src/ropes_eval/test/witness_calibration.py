#!/usr/bin/python3
"""Witness for test/calibration_test.cpp: prints the data and numpy's least-squares fits.

Run with Debian's python3 and python3-numpy:
    /usr/bin/python3 src/ropes_eval/test/witness_calibration.py
and paste the printed values into the test if the data ever change.
"""
import numpy as np

rng = np.random.default_rng(11)
n_cal, n_test = 30, 20
latents = np.round(rng.normal(size=(n_cal + n_test, 3)), 6)
joint = np.round(0.7 * latents[:, 0] - 0.2 * latents[:, 1] + 0.1 * latents[:, 0] ** 2
                 + 0.05 * rng.normal(size=n_cal + n_test) + 0.3, 6)
cal, test = slice(0, n_cal), slice(n_cal, None)


def fmt(m):
    return ",\n".join(", ".join("%.6f" % v for v in row) for row in m)


print("latents [50, 3] =\n" + fmt(latents))
print("joint [50] =\n" + ", ".join("%.6f" % v for v in joint))

# the paper's form: joint from latent 0 alone, np.polyfit of degree 1
scale, offset = np.polyfit(latents[cal, 0], joint[cal], 1)
mse = np.mean((scale * latents[test, 0] + offset - joint[test]) ** 2)
print("affine scale %.17g offset %.17g test mse %.17g" % (scale, offset, mse))

# the whole latent vector: np.linalg.lstsq on [X, 1]
design = np.column_stack([latents[cal], np.ones(n_cal)])
w, *_ = np.linalg.lstsq(design, joint[cal], rcond=None)
mse = np.mean((np.column_stack([latents[test], np.ones(n_test)]) @ w - joint[test]) ** 2)
print("linear weights", ", ".join("%.17g" % v for v in w[:3]), "offset %.17g" % w[3],
      "test mse %.17g" % mse)

# a dead latent (constant 0.25) beside them: the predictions, so the MSE, do not change
dead = np.column_stack([latents, np.full(n_cal + n_test, 0.25)])
design = np.column_stack([dead[cal], np.ones(n_cal)])
w, *_ = np.linalg.lstsq(design, joint[cal], rcond=None)
mse = np.mean((np.column_stack([dead[test], np.ones(n_test)]) @ w - joint[test]) ** 2)
print("with a dead latent: test mse %.17g" % mse)
