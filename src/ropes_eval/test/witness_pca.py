#!/usr/bin/python3
"""Witness for test/pca_test.cpp: prints the data and numpy's principal components.

Run with Debian's python3 and python3-numpy:
    /usr/bin/python3 src/ropes_eval/test/witness_pca.py
and paste the printed values into the test if the data ever change.
"""
import numpy as np

rng = np.random.default_rng(4)
# 30 samples of 4 values, spread 3 / 1.5 / 0.5 / 0.1 along a random rotation, offset
basis, _ = np.linalg.qr(rng.normal(size=(4, 4)))
x = np.round((rng.normal(size=(30, 4)) * [3.0, 1.5, 0.5, 0.1]) @ basis.T + [1, -2, 0.5, 3], 6)
print("x [30, 4] =\n" + ",\n".join(", ".join("%.6f" % v for v in row) for row in x))

# PCA by the SVD of the centred data; each component's largest-magnitude entry positive
centred = x - x.mean(axis=0)
_, s, vt = np.linalg.svd(centred, full_matrices=False)
for i in range(2):
    v = vt[i] * np.sign(vt[i][np.argmax(np.abs(vt[i]))])
    print("component %d =" % i, ", ".join("%.17g" % c for c in v),
          "variance %.17g" % (s[i] ** 2 / (len(x) - 1)))
    print("score of sample 0 on component %d: %.17g" % (i, centred[0] @ v))
