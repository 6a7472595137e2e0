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
