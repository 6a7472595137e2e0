#!/usr/bin/python3
"""Witness for test/correlation_test.cpp: prints the data and scipy's correlations.

Run with Debian's python3 and python3-scipy (apt-get install python3-scipy):
    /usr/bin/python3 src/ropes_eval/test/witness_correlation.py
and paste the printed values into the test if the data ever change.
"""
import numpy as np
import scipy.stats as st

i = np.arange(20)
x = np.sin(i)
y = np.round(x**3 + 0.3 * np.cos(3 * i), 1)  # rounding makes ties
print("x =", repr(x.tolist()))
print("y =", repr(y.tolist()))
print("pearson  %.17g" % st.pearsonr(x, y)[0])
print("spearman %.17g" % st.spearmanr(x, y)[0])
print("ranks(y) =", st.rankdata(y).tolist())

# best-assignment MCC: scipy.optimize.linear_sum_assignment on the |Pearson| matrix. Joints
# 0 and 1 are correlated, and latent 0 follows both: greedy matching (the largest entry
# first) gives latent 0 to joint 0 and leaves joint 1 latent 1; the best assignment swaps them.
from scipy.optimize import linear_sum_assignment


def fmt(m):
    return ",\n".join(", ".join("%.6f" % v for v in row) for row in m)


rng = np.random.default_rng(1)
n = 40
a0 = rng.normal(size=n)
a1 = a0 + 0.5 * rng.normal(size=n)
a2 = rng.normal(size=n)
angles = np.round(np.column_stack([a0, a1, a2]), 6)
latents = np.round(np.column_stack([0.8 * a0 + 0.2 * a1 + 0.1 * rng.normal(size=n),
                                    a0 + 0.6 * rng.normal(size=n), rng.normal(size=n),
                                    -a2 + 0.3 * rng.normal(size=n)]), 6)
print("angles [40, 3] =\n" + fmt(angles))
print("latents [40, 4] =\n" + fmt(latents))
for name, corr in (("pearson", st.pearsonr), ("spearman", st.spearmanr)):
    c = np.abs(np.array([[corr(latents[:, l], angles[:, j])[0] for l in range(4)]
                         for j in range(3)]))
    rows, cols = linear_sum_assignment(c, maximize=True)
    print(name, "abs matrix =", ", ".join("%.17g" % v for v in c.ravel()))
    print(name, "assignment =", cols.tolist(), "mean %.17g" % c[rows, cols].mean())
